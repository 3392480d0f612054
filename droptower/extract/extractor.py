"""Stiffness and damping of one drop test from its signals (Rapp et al. 2022, Fig. 9, eq. 13-18;
docs/theory.md#decay, #extraction, #damping-measures).

Steps: impact onset and pre-trigger baseline (:mod:`.impact_detection`; the pre-trigger means remove
sensor offsets and the preload), starting frequency and decay from the angle after the impact,
the fit window (:mod:`.window`), the angle fit and the torque fit (:mod:`.decay`), then eq.
15-18 (:mod:`droptower.sdof`) with standard uncertainties propagated from the fits.
"""
from __future__ import annotations

import math

import numpy as np

from droptower.errors import DroptowerError, finite_values, not_in_range
from droptower import sdof
from droptower.damped_cosine import TorqueFit, fit_decay, fit_torque, start_frequency_and_decay
from droptower.extract.impact_detection import find_impact
from droptower.extract.result import ExtractionResult
from droptower.propagation import propagate
from droptower.extract.window import MIN_PERIODS, Window
from droptower.io.signals import DropSignals
from droptower.units import GRAVITY_M_PER_S2

POOR_FIT_ERROR = 0.05           # fit_error above this flags poor_fit (5 % of the amplitude)
MIN_SAMPLES_PER_PERIOD = 20     # fewer flags too_few_samples_per_period
CLIP_RUN_FRACTION = 0.02        # clipping: the channel sits at its extreme for this share of a period ...
CLIP_RUN_MIN = 3                # ... and at least this many samples in a row
MIN_FIT_SAMPLES = 8             # fewer samples in the window cannot support the 4-parameter fit


def _check(signals: DropSignals) -> None:
    """Signals built directly (not via :func:`droptower.io.mapping.map_channels`) get the same checks."""
    time = finite_values(signals.time_s, "time_s")
    for name in ("angle_rad", "torque_nm", "impact_force_n"):
        values = getattr(signals, name)
        if values is None:
            continue
        values = finite_values(values, name)  # a gap is refused by name and sample, never filled
        if values.shape != time.shape:
            raise DroptowerError(f"{values.size} samples, time has {time.size}", where=name)
        if np.ptp(values) == 0.0:
            raise DroptowerError(f"constant signal ({float(values[0])!r} throughout)", where=name)
    if time.size < 2:
        raise DroptowerError(f"{time.size} sample(s), at least 2 needed", where="time_s")
    step = np.diff(time)
    if not (step > 0).all():
        i = int(np.argmax(step <= 0))
        kind = "duplicated" if step[i] == 0 else "non-monotonic (goes backwards)"
        raise DroptowerError(f"time is {kind} at sample {i + 1} ({float(time[i])!r} s -> {float(time[i + 1])!r} s)")


def _longest_run_at_extreme(x: np.ndarray) -> int:
    """Longest run of consecutive samples equal to the channel's maximum or minimum."""
    longest = 0
    for at in (x == x.max(), x == x.min()):
        edges = np.diff(np.concatenate([[0], at.view(np.int8), [0]]))
        longest = max(longest, int(np.max(np.flatnonzero(edges == -1) - np.flatnonzero(edges == 1))))
    return longest


def metadata_value(signals: DropSignals, given: float | None, key: str) -> float | None:
    """A positive rig quantity: the given value, else the log's metadata ``key``, else None."""
    value = given if given is not None else signals.metadata.get(key)
    if value is None:
        return None
    try:
        value = float(value)
    except (TypeError, ValueError):
        raise DroptowerError(f"{key} {value!r} is not a number") from None
    if not (math.isfinite(value) and value > 0):
        raise not_in_range(value, key)
    return value


#: log metadata the impact law needs (besides J and L)
IMPACT_LAW_KEYS = ("drop_mass_kg", "drop_height_m", "restitution")


def lever_rate_after(signals: DropSignals, inertia: float, lever_length_m: float | None,
                     impulse_ns: float, gravity_m_per_s2: float = GRAVITY_M_PER_S2) -> tuple[float, str]:
    """The lever's angular rate just after the impact (rad/s) and where it comes from:
    ``"impact_force"`` (L·∫F dt / J), else ``"impact_law"`` (the log's drop mass, height and
    restitution, the free fall under ``gravity_m_per_s2``; Rapp et al. 2022 with momentum
    conservation), else NaN and ``""``."""
    if lever_length_m is None:
        return math.nan, ""
    if math.isfinite(impulse_ns):
        return lever_length_m * impulse_ns / inertia, "impact_force"
    try:
        m1, h, k = (float(signals.metadata[key]) for key in IMPACT_LAW_KEYS)
    except (KeyError, TypeError, ValueError):
        return math.nan, ""
    if not (m1 > 0 and h > 0 and 0 <= k <= 1):
        return math.nan, ""
    from droptower.rig.impact_law import impact_velocities  # here: the rig package imports numba

    return float(impact_velocities(m1, inertia, lever_length_m, h, k, gravity_m_per_s2).rate_after_rad_per_s), \
        "impact_law"


def _derived(theta: np.ndarray, inertia: float, window_s: float, t_from: float, has_torque: bool) -> np.ndarray:
    """f, ω, δ, φ̂, φ̂_ref, c_M1, d_ratio, η, ψ, c_M2, M2/M1 − 1, T̂ from θ = (φ̂, δ, ω, Φ, a, b, offset)."""
    amp, delta, omega, phase, a, b, _ = theta
    c1 = sdof.stiffness(inertia, omega, delta)
    c2 = torque_amplitude = np.nan
    if has_torque:
        torque_amplitude = np.hypot(a, b)
        # first extreme of the fitted angle after the contact: φ' = 0 <=> ωt − Φ = −atan(δ/ω) + kπ;
        # there φ' = 0, so T/φ is the stiffness (eq. 17, c_dyn,M2 = T(φ = φ_max)/φ_max)
        base = (phase - np.arctan2(delta, omega)) / omega
        t_max = base + np.ceil((t_from - base) * omega / np.pi) * np.pi / omega
        env = np.exp(-delta * t_max)
        torque = env * (a * np.cos(omega * t_max) + b * np.sin(omega * t_max))
        c2 = torque / (amp * env * np.cos(omega * t_max - phase))
    return np.array([
        omega / (2 * np.pi), omega, delta, amp, sdof.reference_amplitude(amp, delta, window_s), c1,
        sdof.damping_ratio(delta, omega), sdof.loss_factor(delta, omega),
        sdof.relative_damping(delta, omega), c2, c2 / c1 - 1.0, torque_amplitude,
    ])


_DERIVED_NAMES = ("frequency_hz", "omega_rad_per_s", "delta_per_s", "amplitude_rad", "amplitude_ref_rad",
                  "stiffness_nm_per_rad", "damping_ratio", "loss_factor", "relative_damping_psi",
                  "stiffness_torque_nm_per_rad", "stiffness_deviation", "torque_amplitude_nm")


def extract(signals: DropSignals, *, inertia_kgm2: float | None = None, lever_length_m: float | None = None,
            window: str | Window = "first-cycle", gravity_m_per_s2: float | None = None) -> ExtractionResult:
    """Extract stiffness and damping from one drop test (Rapp et al. 2022, eq. 13-18, docs/theory.md#extraction).

    signals: SI signals of the test; inertia_kgm2: rotating inertia J (default: the log's
    metadata ``inertia_kgm2``); lever_length_m: lever arm L (default: metadata
    ``lever_length_m``), used only for the lever's rate after the impact (L·∫F dt / J, else the
    impact law) and the impact energy; window: ``first-cycle``,
    ``N-cycles`` or seconds; gravity_m_per_s2: g of the impact law's free fall (m/s^2; default:
    the log's metadata ``gravity_m_per_s2``, else :data:`droptower.units.GRAVITY_M_PER_S2`; a rig
    file's value when the extraction is given a rig). Raises :class:`DroptowerError` (naming the source file) for input
    that cannot give a result; :class:`TypeError` for anything but signals.
    """
    signals = _as_signals(signals, inertia_kgm2)
    try:
        inertia = metadata_value(signals, inertia_kgm2, "inertia_kgm2")
        if inertia is None:
            raise DroptowerError("no rotating inertia: the log has no 'inertia_kgm2' metadata; give `inertia_kgm2` "
                                 "(the lever fixture's J; `rig` gives it only for a rig with a single fixture)")
        lever = metadata_value(signals, lever_length_m, "lever_length_m")
        gravity = metadata_value(signals, gravity_m_per_s2, "gravity_m_per_s2") or GRAVITY_M_PER_S2
        return _extract(signals, inertia, lever, Window.parse(window), gravity)
    except DroptowerError as exc:
        raise exc.with_file(signals.source) if signals.source is not None else exc from None


def _as_signals(signals: object, inertia_kgm2: float | None) -> DropSignals:
    """``signals``, or a simulated drop's sensor channels (``DropResult.channels()``) as signals."""
    if isinstance(signals, DropSignals):
        return signals
    if all(hasattr(signals, a) for a in ("time_s", "angle_rad", "torque_nm", "impact_force_n", "laser_distance_m")):
        if inertia_kgm2 is None:  # the rig's channels carry no metadata: name the call that has it
            raise DroptowerError("a simulated drop's channels carry no metadata (no rotating inertia): pass "
                                 "DropResult.signals() instead, or give inertia_kgm2")
        return DropSignals(*(np.asarray(getattr(signals, a), dtype=float)
                             for a in ("time_s", "angle_rad", "torque_nm", "impact_force_n")))
    raise TypeError(f"extract expects DropSignals (droptower.io.map_channels(read_any(path)), DropResult.signals()), "
                    f"got {type(signals).__name__}")


def _extract(signals: DropSignals, inertia: float, lever_length_m: float | None, window: Window,
             gravity_m_per_s2: float = GRAVITY_M_PER_S2) -> ExtractionResult:
    _check(signals)
    time, angle, torque = signals.time_s, signals.angle_rad, signals.torque_nm
    impact = find_impact(time, angle, signals.impact_force_n)
    pre = slice(0, impact.baseline_end)
    angle_offset = float(np.mean(angle[pre]))
    torque_offset = float(np.mean(torque[pre])) if torque is not None else np.nan
    t = time - time[impact.onset]
    y = angle - angle_offset
    after = slice(impact.contact_end, None)
    if t[after].size < 4:
        raise DroptowerError(f"the record ends {t[-1]:.4g} s after the impact")
    noise = float(np.std(angle[pre]))
    omega0, delta0 = start_frequency_and_decay(t[after], y[after], noise)
    period0 = 2 * np.pi / omega0
    wanted = window.length_s(period0)
    end = min(wanted, float(t[-1]))
    if end < MIN_PERIODS * period0:
        raise DroptowerError(f"the record ends {t[-1]:.4g} s after the impact, less than 3/4 of the oscillation "
                             f"period ({period0:.4g} s)")
    sel = np.flatnonzero((t >= t[impact.contact_end]) & (t <= end))
    if sel.size < MIN_FIT_SAMPLES:
        raise DroptowerError(f"only {sel.size} samples in the fit window ({end:.4g} s): the sample rate "
                             f"({signals.sample_rate_hz:.6g} Hz) is too low for the oscillation")
    fit = fit_decay(t[sel], y[sel], omega0, delta0, baseline_var=noise**2 / impact.baseline_end)
    tfit: TorqueFit | None = fit_torque(t[sel], torque[sel] - torque_offset, fit.params[1], fit.params[2]) \
        if torque is not None else None

    theta = np.concatenate([fit.params, tfit.params if tfit else np.zeros(3)])
    cov = np.zeros((7, 7))
    cov[:4, :4] = fit.cov
    if tfit is not None:
        cov[4:, 4:] = tfit.cov  # the two fits are treated as independent
    values, stds = propagate(lambda th: _derived(th, inertia, end, float(t[sel[0]]), tfit is not None), theta, cov)
    derived = dict(zip(_DERIVED_NAMES, values))
    std = {k: float(s) for k, s, v in zip(_DERIVED_NAMES, stds, values) if np.isfinite(v)}

    curve = fit(t[sel])
    peak = float(np.max(np.abs(curve)))
    fit_error = fit.rms / peak
    torque_fit_error = np.nan
    if tfit is not None:
        torque_fit_error = tfit.rms / float(np.max(np.abs(tfit(t[sel]) - tfit.params[2])))
    amp, delta, omega, phase = fit.params
    fs = signals.sample_rate_hz
    spp = fs * 2 * np.pi / omega
    # |φ'(0)| of the fitted decay: depends on the window (the decay is fitted over it), so it has
    # its own name; the lever's rate after the impact comes from the impact alone: the force
    # pulse's angular momentum J·φ'(0) = L·∫F dt, else the impact law on the log's m1, h, k, L
    # (Rapp et al. 2022, section "Theory of Impact Investigation")
    fit_rate = abs(float(amp * (omega * np.sin(phase) - delta * np.cos(phase))))
    rate_after, rate_from = lever_rate_after(signals, inertia, lever_length_m, impact.impulse_ns, gravity_m_per_s2)

    # a second contact counts as a double impact within the first period (docs/theory.md#double-impact, as the
    # rig's check) or the fit window; a later one is reported but does not disturb the fit
    second_after = float(t[impact.second_onset]) if impact.second_onset is not None else np.nan
    double = bool(second_after <= max(2 * np.pi / omega, end))
    flags = []
    if double:
        flags.append("double_impact")
    if impact.source != "impact_force":
        flags.append("double_impact_unchecked")
    clip_run = max(CLIP_RUN_MIN, int(np.ceil(CLIP_RUN_FRACTION * spp)))
    if any(_longest_run_at_extreme(x) >= clip_run for x in (angle, torque) if x is not None):
        flags.append("clipping")
    if spp < MIN_SAMPLES_PER_PERIOD:
        flags.append("too_few_samples_per_period")
    if end < wanted:
        flags.append("short_window")
    if not fit_error <= POOR_FIT_ERROR:
        flags.append("poor_fit")

    return ExtractionResult(
        **{k: float(v) for k, v in derived.items()},
        phase_rad=float(phase),
        torque_phase_rad=float(np.arctan2(tfit.params[1], tfit.params[0])) if tfit else np.nan,
        torque_fit_offset_nm=float(tfit.params[2]) if tfit else np.nan,
        fit_error=float(fit_error), torque_fit_error=float(torque_fit_error),
        impact_time_s=float(time[impact.onset]), window_start_s=float(t[sel[0]]), window_end_s=float(end),
        samples_per_period=float(spp), sample_rate_hz=float(fs),
        angle_offset_rad=angle_offset, torque_offset_nm=torque_offset,
        impact_impulse_ns=impact.impulse_ns, decay_fit_initial_rate_rad_per_s=fit_rate,
        lever_rate_after_rad_per_s=rate_after, lever_rate_after_from=rate_from,
        impact_energy_j=0.5 * inertia * rate_after**2,
        second_impact_after_s=second_after, inertia_kgm2=inertia, double_impact=double, flags=tuple(flags), std=std,
        angle_fit=fit, torque_fit=tfit,
    )
