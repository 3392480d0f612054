"""Drop-test logs -> the measured free decays a coupling model is fitted to (docs/theory.md#decay, #extraction).

Per log: channels mapped as for ``droptower extract``; the impact located by the extractor's
:func:`~droptower.extract.impact_detection.find_impact`; pre-trigger means removed (sensor offsets and
the preload); the lever's rate just after the impact from

- the impact-force channel: omega0 = L * (integral of F dt over the pulse) / J, the impulse's
  moment about the pivot (the pivot's reaction has none), at the pulse's centroid; or
- without a force channel (or lever length), the angle's slope after the onset: a cubic
  through the angle over the first eighth of a period after the contact, its zero before
  the contact is the impact instant and its slope there omega0.

The compared window runs from the end of the contact over ``cycles`` periods, or up to a
later contact of the drop mass (it falls back onto the lever); a log with a second impact
within ``MIN_WINDOW_PERIODS`` periods (a double impact, docs/theory.md#double-impact) is excluded (named, with
the time), like a log that cannot be read or holds no impact; the others go on.
"""
from __future__ import annotations

import functools
import math
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable

import numpy as np

from droptower.errors import DroptowerError, expects, missing_file
from droptower.damped_cosine import start_frequency_and_decay
from droptower.extract.extractor import metadata_value
from droptower.extract.impact_detection import find_impact
from droptower.io.logsettings import LogSettings

#: A later contact of the drop mass ends the compared window; one within this many periods excludes the test.
MIN_WINDOW_PERIODS = 1.5
#: Samples compared per oscillation period (at most; every sample at low sample rates).
COMPARED_PER_PERIOD = 100
#: Fraction of the first period after the contact over which the angle's slope is fitted.
SLOPE_WINDOW_PERIODS = 0.125
#: Logs read at once (threads): the readers (pyarrow's, pandas') and numpy release the GIL for
#: most of a log's reading, so two threads read a campaign's logs in about half the wall time
#: where the process waits for its share of a loaded machine (measured on 450 Table-2 logs,
#: ~0.8 s of CPU time: 6.3 s serial, 2.2 s in two threads at load average 13).
READ_THREADS = 2


@dataclass
class DropDecay:
    """One drop test's measured free decay (SI).

    time_s (N,): compared samples, seconds after the impact instant; angle_rad (N,): angle
    minus its pre-trigger mean; torque_nm (N,) or None: torque minus its pre-trigger mean;
    inertia_kgm2: J; rate0_rad_per_s: the lever's rate just after the impact; rate_source:
    ``impact_force`` or ``angle_slope``; frequency_hz, amplitude_rad: the first cycle's
    frequency and peak angle (for scaling, grids and reports); dt_s: sample step;
    angle_noise_rad: the angle's standard deviation before the trigger (the sensor's noise
    floor, the lever at rest; 0 when unknown).
    """

    name: str
    time_s: np.ndarray
    angle_rad: np.ndarray
    torque_nm: np.ndarray | None
    inertia_kgm2: float
    rate0_rad_per_s: float
    rate_source: str
    frequency_hz: float
    amplitude_rad: float
    dt_s: float
    metadata: dict[str, Any] = field(default_factory=dict)
    angle_noise_rad: float = 0.0

    @property
    def torque_amplitude_nm(self) -> float:
        return float(np.max(np.abs(self.torque_nm))) if self.torque_nm is not None else math.nan


@dataclass(frozen=True)
class ReadSettings(LogSettings):
    """How to read drop-test logs (:class:`~droptower.io.logsettings.LogSettings`: channel roles,
    J / L overrides and fallbacks, e.g. the rig's), ``cycles`` periods compared after the impact,
    ``rate`` (``auto``: the impulse where the log has a force channel and L is known, else the
    angle's slope; ``impulse``; ``slope``)."""

    cycles: float = 3.0
    rate: str = "auto"
    #: the rig's lever fixtures as named in messages, where the rig has several (so it gives no
    #: single inertia): a log without its inertia is then told that its conditions must say which
    rig_fixtures: str | None = None


def _slope_rate(t: np.ndarray, y: np.ndarray, start: int, period_s: float) -> tuple[float, float]:
    """(impact instant, rate just after it) from a cubic through the angle after the contact."""
    sel = np.flatnonzero((t >= t[start]) & (t <= t[start] + SLOPE_WINDOW_PERIODS * period_s))
    if sel.size < 6:
        raise DroptowerError("too few samples after the impact to take the angle's slope "
                             f"({sel.size} in the first eighth of a period)")
    t0 = t[sel[0]]
    c = np.polyfit(t[sel] - t0, y[sel], 3)
    roots = np.roots(c)
    real = roots[np.abs(roots.imag) < 1e-9 * max(1.0, float(np.max(np.abs(roots))))].real
    before = real[(real <= 0.0) & (real >= -SLOPE_WINDOW_PERIODS * period_s)]
    tc = float(before.max()) if before.size else 0.0
    return t0 + tc, float(np.polyval(np.polyder(c), tc))


def decay_from_signals(signals: Any, settings: ReadSettings, name: str) -> DropDecay:
    """The free decay of one test's :class:`~droptower.io.signals.DropSignals`."""
    inertia = metadata_value(signals, settings.inertia_kgm2, "inertia_kgm2") or settings.defaults.get("inertia_kgm2")
    if inertia is None and settings.rig_fixtures is not None:
        raise DroptowerError(f"no rotating inertia: the rig has several lever fixtures ({settings.rig_fixtures}) and "
                             "nothing says which one this log is: give `conditions` (a table with its fixture or "
                             "inertia per file) or `inertia_kgm2`")
    if inertia is None:
        raise DroptowerError("no rotating inertia: the log has no 'inertia_kgm2' metadata; give `inertia_kgm2`, "
                             "`conditions` (per file) or a `rig` with a single fixture")
    lever = metadata_value(signals, settings.lever_length_m, "lever_length_m") or settings.defaults.get("lever_length_m")
    force = signals.impact_force_n if settings.rate != "slope" else None
    if settings.rate == "impulse" and (signals.impact_force_n is None or lever is None):
        raise DroptowerError("rate from the impulse needs an impact-force channel (`roles={'impact_force': 'NAME[:UNIT]'}`) "
                             "and the lever length (`lever_length_m` or `rig`)")
    t_all, angle = np.asarray(signals.time_s, float), np.asarray(signals.angle_rad, float)
    impact = find_impact(t_all, angle, force)
    pre = slice(0, impact.baseline_end)
    y = angle - float(np.mean(angle[pre]))
    t = t_all - t_all[impact.onset]
    after = slice(impact.contact_end, None)
    noise = float(np.std(angle[pre]))
    try:
        period = 2.0 * np.pi / start_frequency_and_decay(t[after], y[after], noise)[0]
    except DroptowerError:
        # no zero crossing: friction holds the lever off its rest (a model can still be fitted);
        # the first extreme comes about a quarter period after the impact
        period = 4.0 * float(t[impact.contact_end + int(np.argmax(np.abs(y[after])))])
    if force is not None and lever is not None:
        pulse = slice(impact.onset - 1, impact.contact_end + 1)
        f = force[pulse] - float(np.median(force[pre]))
        t_impact = float(np.sum(t[pulse] * f) / np.sum(f))   # the pulse's centroid (docs/theory.md#impact)
        rate0, source = lever * impact.impulse_ns / inertia, "impact_force"
    else:
        t_impact, rate0 = _slope_rate(t, y, impact.contact_end, period)
        source = "angle_slope"
    end = t_impact + settings.cycles * period
    if t[-1] < t_impact + 0.75 * period:
        raise DroptowerError(f"the record ends {t[-1]:.4g} s after the impact, less than 3/4 of the period "
                             f"({period:.4g} s)")
    if impact.second_onset is not None and t[impact.second_onset] < end:
        second = t[impact.second_onset] - t_impact
        if second < MIN_WINDOW_PERIODS * period:
            raise DroptowerError(f"double impact {1e3 * second:.2f} ms after the impact ({second / period:.2f} periods; "
                                 f"at least {MIN_WINDOW_PERIODS:g} free periods are needed)")
        end = t[impact.second_onset - 1]  # the decay is free up to the next contact
    # the decay is compared on COMPARED_PER_PERIOD samples per period (the simulation runs
    # on every sample step): more adds no information on a smooth decay, only cost
    stride = max(1, int(period / float(np.median(np.diff(t_all))) / COMPARED_PER_PERIOD))
    sel = np.flatnonzero((t >= t[impact.contact_end]) & (t <= end))[::stride]
    torque = None
    if signals.torque_nm is not None:
        torque = (np.asarray(signals.torque_nm, float) - float(np.mean(signals.torque_nm[pre])))[sel]
    first = sel[t[sel] <= t_impact + 0.5 * period]
    dt = float(np.median(np.diff(t_all)))
    return DropDecay(name, t[sel] - t_impact, y[sel], torque, float(inertia), float(rate0), source,
                     1.0 / period, float(np.max(np.abs(y[first]))), dt, dict(signals.metadata), noise)


@expects(settings="droptower.identify.droplogs.ReadSettings")
def read_decays(paths: Iterable[str | Path], settings: ReadSettings, *,
                threads: int = READ_THREADS) -> tuple[list[DropDecay], list[dict[str, str]]]:
    """The free decays of drop-test logs and campaign folders (their ``logs/``), and the
    excluded ones as {file, reason}. Every problem of one log excludes that log only; a path that
    names nothing is an error naming it (a mistyped argument, not a bad log). ``threads``: logs
    read at once (:data:`READ_THREADS`; 1: one after the other), the result the same."""
    if isinstance(paths, (str, Path)):  # one path, not its characters
        paths = [paths]
    files: list[Path] = []
    for p in map(Path, paths):
        if not p.exists():
            raise missing_file(p)
        if p.is_dir():
            logs = p / "logs" if (p / "logs").is_dir() else p
            found = sorted(f for f in logs.iterdir() if f.suffix in (".parquet", ".csv") and f.is_file())
            if not found:
                raise DroptowerError("no logs (.parquet, .csv) in the folder", file=p)
            files += found
        else:
            files.append(p)
    if threads > 1 and len(files) > 1:  # the logs in the order given, whichever thread read each
        with ThreadPoolExecutor(min(threads, len(files))) as pool:
            outcomes = list(pool.map(functools.partial(_read_decay, settings=settings), files))
    else:
        outcomes = [_read_decay(f, settings) for f in files]
    return ([o for o in outcomes if isinstance(o, DropDecay)], [o for o in outcomes if not isinstance(o, DropDecay)])


def _read_decay(f: Path, settings: ReadSettings) -> DropDecay | dict[str, str]:
    """One log's free decay, or {file, reason} where it is excluded."""
    try:
        signals = settings.read_signals(f, radius_flags="`sensor_radius_m` or `rig`", sample_rate_flag=None)
        return decay_from_signals(signals, settings, f.name)
    except DroptowerError as exc:
        return {"file": str(f), "reason": ": ".join(p for p in (exc.where, exc.problem) if p)}


def first_cycle_readings(decays: list[DropDecay]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(amplitude rad, frequency Hz, K' + i K'' N*m/rad) of each test's first cycles, read as a
    linear coupling's (Rapp et al. 2022, eq. 16; docs/theory.md#decay): K' = J (omega^2 + delta^2),
    K'' = 2 J delta omega, omega and delta from the crossings and the peaks' log decrement. Biased
    by slow relaxation and friction (docs/theory.md#first-cycle): a first guess, not a result."""
    amp, freq, k = [], [], []
    for d in decays:
        try:
            omega, delta = start_frequency_and_decay(d.time_s, d.angle_rad, d.angle_noise_rad)
        except DroptowerError:
            continue
        amp.append(d.amplitude_rad)
        freq.append(omega / (2.0 * np.pi))
        k.append(d.inertia_kgm2 * complex(omega ** 2 + delta ** 2, 2.0 * delta * omega))
    return np.array(amp), np.array(freq), np.array(k, complex)
