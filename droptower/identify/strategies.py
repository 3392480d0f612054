"""Family-specific staged identification (NOTES §2, seeds 000-004).

Every strategy ends in (or consists of) bounded least squares on the torque error
(:func:`~droptower.identify.fit.least_squares_fit`); the stages before it are the papers' own
routes to good starting values, each using the part of the data that shows its effect:

- ``zerodim6`` (seed 000 §5): K1 from static averages (in a periodic steady state the Maxwell
  branches carry no mean torque, so mean torque / mean angle = K1), K2-C2 on slow ramps,
  K3-C3 on the sine sweeps, then all six jointly;
- ``zerodim20`` (seed 000 §4): the six-parameter fit mapped exactly onto the tables and the
  Mullins filter, then all 20 jointly;
- ``elastoslide`` (seed 001 §III.B): phi0, k, k0 from the initial loading curve through the
  loop tips at several amplitudes (eq. 24), then v_r by a batched grid search, k, k0, v_r
  jointly, and p (odd) by walking the candidates while the error falls. phi0 and v_r are
  identifiable only together (see :func:`identify_elastoslide`);
- ``pfeffer`` (seed 002): the analytic route (k1 = static stiffness, alpha = DH - 1, gamma
  from the loss-peak frequency, beta until the loss angle at the layout frequency matches),
  then least squares;
- ``masing`` (seed 003): one global fit, then A, B, k, R, alpha per amplitude level and each
  as a function of amplitude, then the Maxwell stiffnesses per frequency level and as linear
  functions of frequency;
- ``overlay`` (seed 004): the first-harmonic stiffness and damping of every steady block
  mapped with eq. 19-20; the model is a Kelvin-Voigt coupling following the map.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np
from scipy.optimize import brentq, curve_fit, least_squares

from droptower.errors import DroptowerError
from droptower.identify.cycles import Block, blocks, cycles, evaluate_block, local_amplitude_frequency, turning_points
from droptower.identify.data import DataScale, Segment, characteristic_frequency
from droptower.identify.families import (COMMON_OPTIONS, ElastoslideFamily, Family, MasingFamily, OverlayFamily,
                                         PfefferFamily, ZeroDim6, ZeroDim20, family_class, loading_curve)
from droptower.identify.fit import (Counter, FitResult, Identification, Metrics, Parameter, batch_search,
                                    check_in_bounds, clip_to_bounds, least_squares_fit, metrics, simulate,
                                    simulate_rows)
from droptower.rheology import parse_coupling
from droptower.rheology.elements import Pfeffer

#: Records whose characteristic frequency is below this count as quasi-static ramps (Hz).
SLOW_FREQUENCY_HZ = 0.5
#: Relative tolerance of the least-squares stages that only prepare starting values.
STAGE_TOL = 1e-5
#: zerodim20: a lookup-table value may move by this factor from the six-parameter start.
TABLE_RANGE = 3.0


# ---------------------------------------------------------------------------- set-up
@dataclass
class Setup:
    """A family bound to its data, with the starting values.

    given: which initial values came from the user (strategies do not overwrite them with
    their own estimates); bounded: which bounds came from the user (strategies do not
    narrow them).
    """

    family: Family
    x0: np.ndarray
    given: np.ndarray
    bounded: np.ndarray

    @property
    def max_nfev(self) -> int | None:
        return int(self.family.options["max_nfev"]) or None

    def index(self, name: str) -> int:
        return self.family.names.index(name)

    def set_estimate(self, x: np.ndarray, name: str, value: float) -> None:
        """Use a strategy's estimate for ``name`` unless the user gave its initial value."""
        i = self.index(name)
        if not self.given[i] and np.isfinite(value):
            x[i] = clip_to_bounds([self.family.parameters[i]], [value])[0]

    def free(self, names: list[str]) -> np.ndarray:
        mask = np.zeros(len(self.family.names), bool)
        mask[[self.index(n) for n in names]] = True
        return mask

    def fit(self, segments: list[Segment], x: np.ndarray, names: list[str] | None, stage: str,
            per_segment: np.ndarray | None = None, tol: float = 1e-7) -> FitResult:
        free = None if names is None else self.free(names)
        return least_squares_fit(self.family, segments, x, free=free, stage=stage, max_nfev=self.max_nfev,
                                 per_segment=per_segment, tol=tol)


def setup(kind: str, segments: list[Segment], init: dict[str, float] | None = None,
          bounds: dict[str, tuple[float, float]] | None = None, options: dict[str, Any] | None = None,
          file: str | None = None) -> Setup:
    """Bind family ``kind`` to ``segments``: scaled bounds (``bounds`` overrides some), the
    family's first guess, the user's initial values ``init`` (checked against the bounds)."""
    family = family_class(kind)(DataScale.of(segments), options)
    names = family.names
    for what, given in (("initial values", init or {}), ("bounds", bounds or {})):
        unknown = sorted(set(given) - set(names))
        if unknown:
            raise DroptowerError(f"unknown parameter(s) {', '.join(unknown)} in the {what} for model {kind} "
                                 f"(parameters: {', '.join(names)})", file=file)
    bounded = np.zeros(len(names), bool)
    for name, (lo, hi) in (bounds or {}).items():
        i = names.index(name)
        bounded[i] = True
        p = family.parameters[i]
        if not (lo < hi) or (p.log and lo <= 0):
            raise DroptowerError(f"bounds of {name} must satisfy {'0 < ' if p.log else ''}lower < upper, "
                                 f"got [{lo:g}, {hi:g}]", file=file)
        family.parameters[i] = Parameter(p.name, float(lo), float(hi), p.log, p.scale)
    x0 = family.initial()
    given = np.zeros(len(names), bool)
    for name, value in (init or {}).items():
        i = names.index(name)
        check_in_bounds([family.parameters[i]], np.array([float(value)]), file)
        x0[i], given[i] = float(value), True
    return Setup(family, x0, given, bounded)


def _result(s: Setup, segments: list[Segment], x: np.ndarray, stages: list[FitResult], start: float,
            fit: Metrics | None = None, **kw) -> Identification:
    """An :class:`Identification` of one parameter vector ``x`` (the last stage's)."""
    fam = s.family
    final = stages[-1]

    def predict(segs: list[Segment]) -> list[np.ndarray]:
        return simulate(fam, x[None, :], segs)[0]

    return Identification(fam.kind, dict(zip(fam.names, map(float, x))),
                          dict(zip(fam.names, map(float, final.std_error))), final.at_bounds, stages,
                          fit or final.metrics, fam.coupling(x), predict,
                          derived=fam.derived(x), time_s=time.perf_counter() - start, **kw)


# ---------------------------------------------------------------------------- helpers
def static_stiffness(segments: list[Segment]) -> float | None:
    """Mean torque over mean angle in the second half of each preloaded record (N*m/rad).

    Whole cycles are averaged where the second half oscillates. In a periodic steady state a
    Maxwell branch (or the Pfeffer branch) carries no mean torque, so this is the parallel
    static spring (seed 000's K1 "from average values"; seed 002's k_stat). None if no
    record has a mean angle clearly away from 0.
    """
    num = den = 0.0
    for seg in segments:
        x, y = seg.measured_angle, seg.measured_torque
        half = x.size // 2
        cyc = [c for c in cycles(x, seg.dt_s) if c.start >= half]
        a, b = (cyc[0].start, cyc[-1].stop) if len(cyc) >= 2 else (half, x.size)
        ok = np.isfinite(y[a:b])
        if ok.sum() < 2:
            continue
        xm, ym = float(np.mean(x[a:b][ok])), float(np.mean(y[a:b][ok]))
        swing = 0.5 * float(np.ptp(x[a:b]))
        if abs(xm) > 0.1 * swing and abs(xm) > 0.02 * float(np.max(np.abs(x))):
            num += xm * ym
            den += xm * xm
    return num / den if den > 0 else None


def split_by_speed(segments: list[Segment]) -> tuple[list[Segment], list[Segment]]:
    """(quasi-static records, dynamic records) by characteristic frequency."""
    slow = [s for s in segments if characteristic_frequency(s) < SLOW_FREQUENCY_HZ]
    return slow, [s for s in segments if characteristic_frequency(s) >= SLOW_FREQUENCY_HZ]


def sweeps(segments: list[Segment]) -> list[Segment]:
    """Dynamic records made of steady sine blocks (sweeps, sines), not steps or random ones."""
    _, fast = split_by_speed(segments)
    return [s for s in fast if blocks(s.measured_angle, s.dt_s)]


@dataclass(frozen=True)
class SteadyBlock:
    """A block of steady sine cycles in segment ``segment`` (index) with its lab evaluation."""

    segment: int
    block: Block
    window: Segment

    @property
    def amplitude_rad(self) -> float:
        return self.block.amplitude_rad

    @property
    def frequency_hz(self) -> float:
        return self.block.frequency_hz


def steady_blocks(segments: list[Segment]) -> list[SteadyBlock]:
    """Every block of steady sine cycles in the data, as a window of its record (the history
    from the record's start, the torque compared on the block's cycles after the first)."""
    out = []
    for i, seg in enumerate(segments):
        for b in blocks(seg.measured_angle, seg.dt_s):
            out.append(SteadyBlock(i, b, seg.window(b.first_cycle_stop, b.stop,
                                                    name=f"{seg.name} {math.degrees(b.amplitude_rad):.3g} deg "
                                                         f"{b.frequency_hz:.3g} Hz")))
    return out


def levels(values: list[float], rel_tol: float = 0.1) -> list[list[int]]:
    """Indices of ``values`` grouped into levels (sorted; a new level starts more than
    ``rel_tol`` above the level's first value)."""
    order = np.argsort(values)
    out: list[list[int]] = []
    for i in order:
        if out and values[i] <= values[out[-1][0]] * (1 + rel_tol):
            out[-1].append(int(i))
        else:
            out.append([int(i)])
    return out


# ---------------------------------------------------------------------------- seed 000
def _zerodim6(s: Setup, segments: list[Segment]) -> tuple[np.ndarray, list[FitResult], dict]:
    x = s.x0.copy()
    stages: list[FitResult] = []
    extra: dict[str, Any] = {}
    k1 = static_stiffness(segments)
    if k1 is not None and k1 > 0:
        s.set_estimate(x, "k1_nm_per_rad", k1)
        extra["k1_static_average_nm_per_rad"] = k1
    # the branch stages only give starting values for the joint fit: a looser tolerance
    slow, _ = split_by_speed(segments)
    if slow:
        names = ["k2_nm_per_rad", "tau2_s"] + ([] if k1 else ["k1_nm_per_rad"])
        r = s.fit(slow, x, names, "K2-C2 on slow ramps", tol=STAGE_TOL)
        x, stages = r.values.copy(), stages + [r]
    fast = sweeps(segments) or split_by_speed(segments)[1]
    if fast:
        r = s.fit(fast, x, ["k3_nm_per_rad", "k3_gain_nm_per_rad2", "tau3_s"], "K3-C3 on sweeps", tol=STAGE_TOL)
        x, stages = r.values.copy(), stages + [r]
    r = s.fit(segments, x, None, "joint")
    return r.values.copy(), stages + [r], extra


def identify_zerodim6(s: Setup, segments: list[Segment], start: float, **_) -> Identification:
    x, stages, extra = _zerodim6(s, segments)
    return _result(s, segments, x, stages, start, extra=extra)


def branch_ranges(v6: np.ndarray, segments: list[Segment]) -> tuple[float, float]:
    """Largest deformation of the K3 spring and largest rate of the C3 dashpot (rad, rad/s)
    that the six-parameter model ``v6`` visits on ``segments``: where seed 000's lookup tables
    of the same branch need their breakpoints."""
    k3, gain, tau3 = v6[3], v6[4], v6[5]
    six = ZeroDim6(DataScale.of(segments))
    branch = parse_coupling({"element": [six.elements(v6)[2]]})  # the variable Maxwell branch alone
    t3 = np.concatenate([np.abs(branch.respond(seg.angle_rad, seg.dt_s)) for seg in segments])
    peak = float(t3.max())
    e_max = 2 * peak / (k3 + math.sqrt(k3 * k3 + 4 * gain * peak)) if gain > 0 else peak / k3
    return e_max, peak / (k3 * tau3)


def identify_zerodim20(s: Setup, segments: list[Segment], start: float, previous: dict | None = None,
                       **_) -> Identification:
    fam: ZeroDim20 = s.family  # type: ignore[assignment]
    x = s.x0.copy()
    stages: list[FitResult] = []
    if not s.given.all():
        six = (previous or {}).get("zerodim6")
        if six is None:
            opts = {k: v for k, v in fam.options.items() if k in COMMON_OPTIONS}
            s6 = setup("zerodim6", segments, options=opts)
            v6, stages, _ = _zerodim6(s6, segments)
        else:
            v6 = np.array(list(six.parameters.values()))
        e_max, v_max = branch_ranges(v6, segments)
        fam.set_breakpoints(float(fam.options["deformation_max_rad"]) or e_max,
                            float(fam.options["rate_max_rad_per_s"]) or v_max)
        for i, (name, value) in enumerate(zip(fam.names, fam.from_zerodim6(v6))):
            s.set_estimate(x, name, value)
            p = fam.parameters[i]
            if i >= 3 and not s.bounded[i]:
                # seed 000: "sound constraints" - a table value stays within a factor of
                # TABLE_RANGE of the six-parameter start, so a breakpoint the data hardly reach
                # cannot run off (and spoil the model just beyond the fitting data)
                fam.parameters[i] = Parameter(p.name, max(p.lower, x[i] / TABLE_RANGE), min(p.upper, x[i] * TABLE_RANGE),
                                              p.log, p.scale)
                x[i] = clip_to_bounds([fam.parameters[i]], [x[i]])[0]
    r = s.fit(segments, x, None, "joint (20 parameters)")
    extra = {"deformation_breakpoints_rad": fam.deformation_rad.tolist(),
             "rate_breakpoints_rad_per_s": fam.rate_rad_per_s.tolist()}
    return _result(s, segments, r.values.copy(), stages + [r], start, extra=extra)


# ---------------------------------------------------------------------------- seed 001
def loop_tips(segments: list[Segment]) -> tuple[np.ndarray, np.ndarray]:
    """Seed 001 Fig. 10: points of the initial loading curve from steady loops.

    For every steady block: the half swing of the angle between its turning points, and half
    the difference of the torques AT those turning points (the loop tips, where the rate is
    zero), averaged over the block's cycles after the first. Returns (A rad, T N*m), sorted.
    """
    amps, torques = [], []
    for sb in steady_blocks(segments):
        seg = segments[sb.segment]
        x, y = seg.measured_angle, seg.measured_torque
        b = sb.block
        tp = turning_points(x[b.start:b.stop]) + b.start
        tp = tp[tp >= b.first_cycle_stop]
        if tp.size < 2 or not np.isfinite(y[tp]).all():
            continue
        dx = np.abs(np.diff(x[tp]))
        dy = np.abs(np.diff(y[tp]))
        amps.append(0.5 * float(np.mean(dx)))
        torques.append(0.5 * float(np.mean(dy)))
    order = np.argsort(amps)
    return np.asarray(amps)[order], np.asarray(torques)[order]


def fit_loading_curve(amplitude_rad: np.ndarray, torque_nm: np.ndarray) -> tuple[float, float, float] | None:
    """Seed 001 eq. 24 through the loop tips by least squares: (phi0 1/(N*m), k, k0 N*m/rad).

    Needs at least three amplitude levels spanning a factor of 1.5; else None.
    """
    a, t = np.asarray(amplitude_rad), np.asarray(torque_nm)
    if a.size < 3 or a.max() < 1.5 * a.min():
        return None
    k_tot = t[0] / a[0]
    k0 = max((t[-1] - t[-2]) / max(a[-1] - a[-2], 1e-300), 1e-3 * k_tot)
    k0 = min(k0, 0.9 * k_tot)
    f_slip = max(t[-1] - k0 * a[-1], 1e-3 * t[-1])
    z0 = np.log([1.0 / f_slip, k_tot - k0, k0])

    def resid(z):
        phi0, k, kk0 = np.exp(z)
        return (loading_curve(a, phi0, k, kk0) - t) / t.max()

    r = least_squares(resid, z0, method="trf", bounds=(z0 - 12, z0 + 12))
    return tuple(map(float, np.exp(r.x))) if r.success else None  # type: ignore[return-value]


def identify_elastoslide(s: Setup, segments: list[Segment], start: float, **_) -> Identification:
    """Seed 001's route. Any angle history gives the same torque for (phi0, v_r) and
    (phi0 / a, v_r a^p), so phi0 is taken from the loop-tip loading curve (eq. 24, as seed 001
    does) and the identifiable combination is reported as the mean slip torque of the yield
    distribution when sliding at 1 rad/s, (1/phi0) (1 rad/s / v_r)^(1/p)."""
    fam: ElastoslideFamily = s.family  # type: ignore[assignment]
    x = s.x0.copy()
    extra: dict[str, Any] = {}
    amps, tips = loop_tips(segments)
    curve = fit_loading_curve(amps, tips)
    extra["loop_tips"] = {"amplitude_rad": amps.tolist(), "torque_nm": tips.tolist()}
    if curve is not None:
        for name, value in zip(("phi0_per_nm", "k_nm_per_rad", "k0_nm_per_rad"), curve):
            s.set_estimate(x, name, value)
        extra["loading_curve"] = dict(zip(("phi0_per_nm", "k_nm_per_rad", "k0_nm_per_rad"), curve))
    # v_r for the middle exponent by a grid search, every candidate in one call of the core
    p_list = sorted(int(p) for p in fam.options["p_candidates"])
    iv, ip = s.index("v_r_rad_per_s"), s.index("p")
    if not s.given[ip]:
        x[ip] = p_list[len(p_list) // 2]
    counter = Counter()
    if not s.given[iv]:
        cands = np.repeat(x[None, :], 11, axis=0)
        cands[:, iv] = np.geomspace(1e-4, 10.0, 11) * fam.scale.rate_rad_per_s
        cands = np.array([clip_to_bounds(fam.parameters, c) for c in cands])
        best, costs = batch_search(fam, segments, cands, counter)
        x = cands[best].copy()
        extra["v_r_search"] = {"p": int(x[ip]), "v_r_rad_per_s": cands[:, iv].tolist(),
                               "sum_squared_error_nm2": costs.tolist()}
    extra["search_evaluations"] = counter.evaluations
    # phi0 stays at the loading-curve value: the model is invariant under phi0 -> phi0 / a,
    # v_r -> v_r a^p (every slider's f* scales by a, and v_r (k e / f*)^p is unchanged), so
    # only v_r phi0^p is identifiable; seed 001 fixes phi0 by the loading curve the same way
    continuous = ["k_nm_per_rad", "k0_nm_per_rad", "v_r_rad_per_s"] + fam.names[5:]
    fits = {int(x[ip]): s.fit(segments, x, continuous, f"joint at p = {int(x[ip])}")}
    if not s.given[ip]:
        # walk p over the odd candidates while the cost falls. Moving to p', v_r is moved so
        # that the slip-rate law (v / v_r)^(1/p) keeps its value at the data's rms rate.
        v_typ = float(np.sqrt(np.mean(np.concatenate([np.diff(g.angle_rad) ** 2 / g.dt_s ** 2 for g in segments]))))

        def try_p(p_new: int, frm: FitResult) -> FitResult:
            start_x = frm.values.copy()
            p_old = int(start_x[ip])
            start_x[iv] = v_typ * (start_x[iv] / v_typ) ** (p_new / p_old)
            start_x[ip] = p_new
            return s.fit(segments, clip_to_bounds(fam.parameters, start_x), continuous, f"joint at p = {p_new}")

        i0 = p_list.index(int(x[ip]))
        for step in (-1, 1):
            i = i0
            while 0 <= i + step < len(p_list):
                here = fits[p_list[i]]
                nxt = fits.get(p_list[i + step]) or try_p(p_list[i + step], here)
                fits[p_list[i + step]] = nxt
                if nxt.metrics.rmse_nm >= here.metrics.rmse_nm:
                    break
                i += step
    best = min(fits.values(), key=lambda r: r.metrics.rmse_nm)
    extra["p_walk"] = {int(p): r.metrics.nrmse for p, r in sorted(fits.items())}
    stages = [r for _, r in sorted(fits.items())]
    stages.remove(best)
    return _result(s, segments, best.values.copy(), stages + [best], start, extra=extra)


# ---------------------------------------------------------------------------- seed 002
def pfeffer_complex_stiffness(v: np.ndarray, omega: np.ndarray | float) -> np.ndarray:
    """K*(Omega) of the linear Pfeffer model with parameters (k1, alpha, beta, gamma)."""
    k1, alpha, beta, gamma = v
    return Pfeffer(kind="pfeffer", k1=k1, alpha=alpha, beta=beta, gamma=gamma).complex_stiffness(np.asarray(omega))


def pfeffer_analytic(k_stat: float, k_dyn: float, loss_angle_rad: float, layout_frequency_hz: float,
                     peak_frequency_hz: float) -> dict[str, Any]:
    """Seed 002's analytic identification of the linear Pfeffer model (NOTES §2.3).

    k1 = k_stat; k2 = k_stat (DH - 1) with DH = k_dyn / k_stat, so alpha = DH - 1; gamma puts
    the loss-angle peak of the beta = 0 model (k1 || Maxwell(k2, c1): tan delta peaks at
    Omega tau = 1/sqrt(1 + alpha), tau = gamma / alpha) at ``peak_frequency_hz``; beta is
    raised from 0 until the loss angle at the layout frequency equals ``loss_angle_rad``.
    Returns the parameters and notes on what could not be met.
    """
    notes = []
    dh = k_dyn / k_stat
    alpha = dh - 1.0
    if alpha <= 0:
        notes.append(f"dynamic hardening {dh:.3g} <= 1: alpha set to 1e-3")
        alpha = 1e-3
    gamma = alpha / (2 * np.pi * peak_frequency_hz * np.sqrt(1.0 + alpha))
    w = 2 * np.pi * layout_frequency_hz

    def miss(beta: float) -> float:
        return float(np.angle(pfeffer_complex_stiffness(np.array([k_stat, alpha, beta, gamma]), w))) - loss_angle_rad

    beta_max = 1e3
    if miss(0.0) >= 0:
        beta = 0.0
        notes.append("the loss angle at the layout frequency is reached without c2 (beta = 0)")
    elif miss(beta_max) < 0:
        beta = beta_max
        notes.append(f"the loss angle at the layout frequency is not reached up to beta = {beta_max:g}")
    else:
        beta = float(brentq(miss, 0.0, beta_max, xtol=1e-12, rtol=1e-10))
    v = np.array([k_stat, alpha, beta, gamma])
    k = complex(pfeffer_complex_stiffness(v, w))
    return {"k1_nm_per_rad": k_stat, "alpha": alpha, "beta": beta, "gamma_s": gamma,
            "dynamic_hardening": dh, "layout_frequency_hz": layout_frequency_hz,
            "peak_frequency_hz": peak_frequency_hz,
            "model_dynamic_stiffness_nm_per_rad": abs(k), "model_loss_angle_deg": math.degrees(np.angle(k)),
            "measured_dynamic_stiffness_nm_per_rad": k_dyn, "measured_loss_angle_deg": math.degrees(loss_angle_rad),
            "notes": notes}


def identify_pfeffer(s: Setup, segments: list[Segment], start: float, **_) -> Identification:
    fam: PfefferFamily = s.family  # type: ignore[assignment]
    x = s.x0.copy()
    extra: dict[str, Any] = {}
    evals = [(sb, evaluate_block(segments[sb.segment].measured_angle, segments[sb.segment].measured_torque,
                                 segments[sb.segment].dt_s, sb.block)) for sb in steady_blocks(segments)]
    evals = [(sb, ev) for sb, ev in evals if ev is not None]
    k_stat = static_stiffness(segments)
    if k_stat is None:
        slow, _ = split_by_speed(segments)
        if slow:  # regression slope of the quasi-static records
            xs = np.concatenate([g.measured_angle for g in slow])
            ys = np.concatenate([g.measured_torque for g in slow])
            ok = np.isfinite(ys)
            k_stat = float(xs[ok] @ ys[ok] / (xs[ok] @ xs[ok]))
        elif evals:  # the storage stiffness at the lowest frequency measured
            k_stat = min(evals, key=lambda e: e[1].frequency_hz)[1].storage_stiffness_nm_per_rad
    if evals and k_stat and k_stat > 0:
        freqs = np.array([ev.frequency_hz for _, ev in evals])
        f_layout = float(fam.options["layout_frequency_hz"]) or float(np.median(freqs))
        near = np.abs(np.log(freqs / f_layout)) <= np.log(1.1)
        if not near.any():
            raise DroptowerError(f"no steady sine block near the layout frequency {f_layout:g} Hz "
                                 f"(blocks at {', '.join(f'{f:.3g}' for f in sorted(set(freqs.round(3))))} Hz)")
        k_star = np.mean([ev.complex_stiffness_nm_per_rad for (_, ev), n in zip(evals, near) if n])
        f_peak = float(fam.options["peak_frequency_hz"]) or f_layout / 5.0
        analytic = pfeffer_analytic(k_stat, abs(k_star), float(np.angle(k_star)), f_layout, f_peak)
        extra["analytic"] = analytic
        for name in fam.names:
            s.set_estimate(x, name, analytic[name])
        extra["analytic_nrmse"] = metrics(segments, simulate(fam, clip_to_bounds(fam.parameters, x)[None], segments)[0]).nrmse
    r = s.fit(segments, x, None, "least squares")
    return _result(s, segments, r.values.copy(), [r], start, extra=extra)


# ---------------------------------------------------------------------------- seed 003
def fit_function(x: np.ndarray, y: np.ndarray, std: np.ndarray | None = None, form: str = "auto") -> dict[str, Any]:
    """A parameter as a function of amplitude or frequency (seed 003).

    Forms: ``constant``, ``poly1``, ``poly4`` (degree up to 4, at most n - 2), ``exp``
    (a + b exp(-c x)), or ``auto``: the form with the lowest corrected Akaike criterion
    among those with fewer coefficients than points - 1 (poly1 for three points or fewer).
    Points are weighted by 1 / ``std`` (the per-level standard errors), so a level whose
    value the data hardly determine does not bend the function.
    Returns {"form", "coefficients" (highest power first for polynomials), "rms_error"}.
    """
    x, y = np.asarray(x, float), np.asarray(y, float)
    n = x.size
    sd = np.ones(n) if std is None else np.asarray(std, float)
    sd = np.where(np.isfinite(sd) & (sd > 0), sd, np.nanmax(np.where(np.isfinite(sd), sd, 0.0)) or 1.0)
    sd = np.maximum(sd, 1e-9 * max(float(np.max(np.abs(y))), 1e-300))
    if form not in ("auto", "constant", "poly1", "poly4", "exp"):
        raise DroptowerError(f"unknown function form {form!r} (constant, poly1, poly4, exp, auto)")
    if form == "auto":
        forms = ["constant", "poly1"] if n <= 3 else ["constant", "poly1", "poly4", "exp"]
    else:
        forms = [form]
    best = None
    for f in forms:
        if f == "constant" or (f.startswith("poly") and n == 1):
            coef = np.array([np.average(y, weights=sd ** -2)])
            pred = np.full(n, coef[0])
            name = "constant"
        elif f.startswith("poly"):
            deg = min(int(f[4:]), max(n - 2, 1))
            coef = np.polyfit(x, y, deg, w=1.0 / sd)
            pred = np.polyval(coef, x)
            name = f"poly{deg}"
        else:
            if n < 4:
                continue
            try:
                coef, _ = curve_fit(lambda t, a, b, c: a + b * np.exp(-c * t), x, y, sigma=sd, maxfev=4000,
                                    p0=[y[np.argmax(x)], y[np.argmin(x)] - y[np.argmax(x)], 1.0 / max(np.ptp(x), 1e-300)])
            except (RuntimeError, ValueError):
                continue
            pred = coef[0] + coef[1] * np.exp(-coef[2] * x)
            name = "exp"
        k = coef.size
        chi2 = float(np.sum(((pred - y) / sd) ** 2))
        aicc = chi2 + 2 * k + (2 * k * (k + 1) / (n - k - 1) if n - k - 1 > 0 else 0.0)
        if best is None or aicc < best[0]:
            best = (aicc, {"form": name, "coefficients": [float(c) for c in coef],
                           "rms_error": float(np.sqrt(np.mean((pred - y) ** 2)))})
    return best[1]  # type: ignore[index]


def eval_function(fn: dict[str, Any], x: float) -> float:
    c = fn["coefficients"]
    if fn["form"] == "constant":
        return c[0]
    if fn["form"] == "exp":
        return c[0] + c[1] * math.exp(-c[2] * x)
    return float(np.polyval(c, x))


def identify_masing(s: Setup, segments: list[Segment], start: float, **_) -> Identification:
    fam: MasingFamily = s.family  # type: ignore[assignment]
    nm = fam.n_masing
    masing_names, maxwell_names = fam.names[:nm], fam.names[nm:]
    glob = s.fit(segments, s.x0.copy(), None, "global (all data)")
    stages = [glob]
    x = glob.values.copy()
    steady = steady_blocks(segments)
    extra: dict[str, Any] = {"amplitude_levels": [], "frequency_levels": []}
    if not steady:
        extra["note"] = "no steady sine blocks: one parameter set identified on all data"
        return _result(s, segments, x, stages, start, extra=extra,
                       coupling_note="one parameter set for all data (no steady sine blocks)")

    # 1. Masing parameters per amplitude level (all frequencies of that level)
    amp_levels = levels([sb.amplitude_rad for sb in steady])
    per_amp = []
    for members in amp_levels:
        wins = [steady[i].window for i in members]
        amp_deg = math.degrees(float(np.median([steady[i].amplitude_rad for i in members])))
        r = s.fit(wins, x, masing_names, f"Masing at {amp_deg:.3g} deg")
        stages.append(r)
        per_amp.append((amp_deg, r))
        extra["amplitude_levels"].append({"amplitude_deg": amp_deg, "blocks": len(members),
                                          **{n: float(v) for n, v in zip(fam.names[:nm], r.values[:nm])},
                                          **{f"{n}_std": float(v) for n, v in zip(fam.names[:nm], r.std_error[:nm])},
                                          "nrmse": r.metrics.nrmse})
    form = str(fam.options["amplitude_function"])
    amp_x = np.array([a for a, _ in per_amp])
    amp_fn = {n: fit_function(amp_x, np.array([r.values[i] for _, r in per_amp]),
                              np.array([r.std_error[i] for _, r in per_amp]), form)
              for i, n in enumerate(masing_names)}

    def masing_at(amp_deg: float) -> np.ndarray:
        a = float(np.clip(amp_deg, amp_x.min(), amp_x.max()))  # no extrapolation beyond the levels
        v = x.copy()
        v[:nm] = [eval_function(amp_fn[n], a) for n in masing_names]
        return clip_to_bounds(fam.parameters, v)

    # 2. Maxwell stiffnesses per frequency level, the Masing part at each block's amplitude.
    # One frequency determines two numbers of the Maxwell part (its K' and K''), so the
    # relaxation times stay at the global fit's and the two stiffnesses are fitted
    maxwell_free = [n for n in maxwell_names if n.startswith("c")]
    freq_levels = levels([sb.frequency_hz for sb in steady])
    per_freq = []
    for members in freq_levels:
        wins = [steady[i].window for i in members]
        base = np.array([masing_at(math.degrees(steady[i].amplitude_rad)) for i in members])
        f_hz = float(np.median([steady[i].frequency_hz for i in members]))
        r = s.fit(wins, base[0], maxwell_free, f"Maxwell at {f_hz:.3g} Hz", per_segment=base)
        stages.append(r)
        per_freq.append((f_hz, r))
        extra["frequency_levels"].append({"frequency_hz": f_hz, "blocks": len(members),
                                          **{n: float(r.values[nm + j]) for j, n in enumerate(maxwell_names)},
                                          "nrmse": r.metrics.nrmse})
    freq_x = np.array([f for f, _ in per_freq])
    freq_fn = {n: fit_function(freq_x, np.array([r.values[nm + j] for _, r in per_freq]),
                               np.array([r.std_error[nm + j] for _, r in per_freq]), "poly1")
               for j, n in enumerate(maxwell_names)}

    def params_at(amp_deg: float, f_hz: float) -> np.ndarray:
        v = masing_at(amp_deg)
        f = float(np.clip(f_hz, freq_x.min(), freq_x.max()))
        v[nm:] = [eval_function(freq_fn[n], f) for n in maxwell_names]
        return clip_to_bounds(fam.parameters, v)

    extra["amplitude_functions"] = {n: {**fn, "variable": "amplitude_deg"} for n, fn in amp_fn.items()}
    extra["frequency_functions"] = {n: {**fn, "variable": "frequency_hz"} for n, fn in freq_fn.items()}
    # fit quality of the amplitude/frequency-dependent model: each block with its own set
    rows = np.array([params_at(math.degrees(sb.amplitude_rad), sb.frequency_hz) for sb in steady])
    wins = [sb.window for sb in steady]
    fit_metrics = metrics(wins, simulate_rows(fam, rows, wins, np.arange(len(wins))))
    amp_out, f_out = float(fam.options["amplitude_deg"]), float(fam.options["frequency_hz"])
    if amp_out or f_out:
        amp_out = amp_out or float(np.median(amp_x))
        f_out = f_out or float(np.median(freq_x))
        v_out = params_at(amp_out, f_out)
        note = (f"one parameter set of the amplitude/frequency-dependent model, at amplitude {amp_out:.4g} deg and "
                f"frequency {f_out:.4g} Hz (identified levels: {', '.join(f'{a:.3g}' for a in amp_x)} deg; "
                f"{', '.join(f'{f:.3g}' for f in freq_x)} Hz)")
        extra["written_at"] = {"amplitude_deg": amp_out, "frequency_hz": f_out}
    else:
        v_out = x
        note = ("the global fit, one parameter set for all data; the amplitude- and frequency-dependent "
                "parameters are in the report (options amplitude_deg / frequency_hz write them at one point)")
    result = _result(s, segments, v_out, stages, start, extra=extra, coupling_note=note, fit=fit_metrics)
    # standard errors: the global fit's for the global set, else per level (in the report)
    result.std_error = dict(zip(fam.names, map(float, glob.std_error))) if v_out is x else \
        {n: float("nan") for n in fam.names}
    result.at_bounds = sorted({b for st in stages for b in st.at_bounds})
    return result


# ---------------------------------------------------------------------------- seed 004
def kelvin_voigt_from_map(fitted: Any, amplitude_deg: np.ndarray, frequency_hz: np.ndarray
                          ) -> tuple[np.ndarray, np.ndarray]:
    """Spring (N*m/rad) and dashpot (N*m*s/rad) of the Kelvin-Voigt coupling that has the map's
    stiffness and damping ratio at (amplitude, frequency), clipped into the measured range.

    The map's damping ratio is the drop tower's d = E_diss / E_el; the Kelvin-Voigt coupling
    with that d swinging at its damped frequency has r = delta / omega = ln(1 + 2 d) / (4 pi)
    and loss factor eta = 2 r / (1 + r^2) (NOTES §1.4, §1.7), so c = eta k / Omega.
    """
    r = fitted.range
    a = np.clip(amplitude_deg, r.amplitude_deg_min, r.amplitude_deg_max)
    f = np.clip(frequency_hz, r.frequency_hz_min, r.frequency_hz_max)
    k = np.degrees(1.0) * fitted.stiffness_nm_per_deg(a, f)  # N*m/deg -> N*m/rad
    ratio = np.log1p(2.0 * np.maximum(fitted.damping_ratio(a, f), 0.0)) / (4.0 * np.pi)
    eta = 2.0 * ratio / (1.0 + ratio ** 2)
    return k, eta * k / (2.0 * np.pi * f)


def identify_overlay(s: Setup, segments: list[Segment], start: float, **_) -> Identification:
    """Seed 004's map as a model. Every steady sine block is evaluated like a servo test
    (K', loss factor); the map (eq. 19 for the stiffness K', eq. 20 for the drop-tower damping
    ratio equivalent to the loss factor, :func:`droptower.servo.drop_tower_equivalent_damping_ratio`)
    is fitted with :func:`droptower.maps.fit.fit_map`. The model's torque is k theta + c dtheta/dt
    with k, c from the map at the amplitude and frequency of the half cycle each sample lies in
    (the same as the core's spring + dashpot, which have no memory). Limits: a Kelvin-Voigt
    coupling has one stiffness for the mean load and the oscillation (a preload is carried at
    the dynamic stiffness), elliptic loops only, no relaxation, no amplitude memory; outside
    the measured amplitude/frequency range the map is held at its edge."""
    import pandas as pd

    from droptower.maps.fit import fit_map
    from droptower.servo import drop_tower_equivalent_damping_ratio

    fam: OverlayFamily = s.family  # type: ignore[assignment]
    rows = []
    for sb in steady_blocks(segments):
        seg = segments[sb.segment]
        ev = evaluate_block(seg.measured_angle, seg.measured_torque, seg.dt_s, sb.block)
        if ev is not None and ev.storage_stiffness_nm_per_rad > 0:
            eta = ev.loss_stiffness_nm_per_rad / ev.storage_stiffness_nm_per_rad
            rows.append({"file": sb.window.name, "amplitude_deg": math.degrees(ev.angle_amplitude_rad),
                         "frequency_hz": ev.frequency_hz,
                         "stiffness_nm_per_deg": ev.storage_stiffness_nm_per_rad * math.pi / 180.0,
                         "damping_ratio": float(drop_tower_equivalent_damping_ratio(eta))})
    table = pd.DataFrame(rows, columns=["file", "amplitude_deg", "frequency_hz", "stiffness_nm_per_deg",
                                        "damping_ratio"])
    try:
        fitted = fit_map(table, source="steady sine blocks")
    except DroptowerError as exc:
        raise DroptowerError(f"model overlay needs steady sine blocks at several amplitudes and frequencies; "
                             f"{len(rows)} found: {exc.problem}") from None

    def predict(segs: list[Segment]) -> list[np.ndarray]:
        out = []
        for seg in segs:
            amp, freq = local_amplitude_frequency(seg.angle_rad, seg.dt_s)
            k, c = kelvin_voigt_from_map(fitted, np.degrees(amp), freq)
            rate = np.diff(seg.angle_rad, prepend=0.0) / seg.dt_s  # the core's dashpot: rate of the step
            out.append(k * seg.angle_rad + c * rate)
        return out

    fit_metrics = metrics(segments, predict(segments))
    amp_out = float(fam.options["amplitude_deg"]) or float(table["amplitude_deg"].median())
    f_out = float(fam.options["frequency_hz"]) or float(table["frequency_hz"].median())
    k_out, c_out = (float(v) for v in kelvin_voigt_from_map(fitted, np.array(amp_out), np.array(f_out)))
    v_out = np.array([k_out, c_out])
    stage = FitResult("map (seed 004 eq. 19-20) by droptower.maps.fit_map", fam.names, v_out,
                      np.ones(2, bool), np.full(2, np.nan), list(fitted.at_bounds), fit_metrics, 0, 0, 0, 0,
                      time.perf_counter() - start, True, "map fitted")
    names = [f"{k}_{u}" for k, u in zip(fitted.coefficients, _map_units())]
    result = Identification(
        fam.kind, dict(zip(names, fitted.coefficients.values())), dict(zip(names, fitted.uncertainties.values())),
        [f"{k}_{u}" for k, u in zip(fitted.coefficients, _map_units()) if k in fitted.at_bounds], [stage],
        fit_metrics, fam.coupling(v_out, description=f"{fam.title}; Kelvin-Voigt at {amp_out:.4g} deg, {f_out:.4g} Hz"),
        predict, derived={"k_nm_per_rad": k_out, "c_nms_per_rad": c_out},
        coupling_note=(f"a Kelvin-Voigt coupling with the map's stiffness and damping at amplitude {amp_out:.4g} deg "
                       f"and frequency {f_out:.4g} Hz (map range {fitted.range.amplitude_deg_min:.3g}-"
                       f"{fitted.range.amplitude_deg_max:.3g} deg, {fitted.range.frequency_hz_min:.3g}-"
                       f"{fitted.range.frequency_hz_max:.3g} Hz)"),
        extra={"map": fitted.to_dict(), "blocks": rows,
               "written_at": {"amplitude_deg": amp_out, "frequency_hz": f_out}})
    return result


def _map_units() -> list[str]:
    from droptower.maps.mapfit import UNITS

    return list(UNITS.values())


STRATEGIES: dict[str, Callable[..., Identification]] = {
    "zerodim6": identify_zerodim6, "zerodim20": identify_zerodim20, "elastoslide": identify_elastoslide,
    "pfeffer": identify_pfeffer, "masing": identify_masing, "overlay": identify_overlay,
}


def identify(kind: str, segments: list[Segment], *, init: dict[str, float] | None = None,
             bounds: dict[str, tuple[float, float]] | None = None, options: dict[str, Any] | None = None,
             holdout: list[Segment] | None = None, previous: dict[str, Identification] | None = None,
             file: str | None = None) -> Identification:
    """Identify model family ``kind`` from ``segments`` (see the module docstring).

    init, bounds, options: from ``--params INIT.toml`` (parameter name -> initial value;
    name -> [lower, upper]; family options); holdout: data for the hold-out RMSE;
    previous: results of other families on the same data (zerodim20 starts from zerodim6's).
    A fit that does not converge is returned with ``converged`` False: the caller decides.
    """
    start = time.perf_counter()
    if not segments:
        raise DroptowerError("no data to identify from")
    s = setup(kind, segments, init, bounds, options, file)
    result = STRATEGIES[kind](s, segments, start, previous=previous)
    if holdout:
        result.evaluate_holdout(holdout)
    result.time_s = time.perf_counter() - start
    return result
