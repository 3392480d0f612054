"""Raw servo-hydraulic time records evaluated as a lab's bench software does (SI inside).

A lab whose bench software does not evaluate has time records only: time (or a sample
interval), the imposed angle or displacement, the measured torque or force; one file per test
or one file holding several amplitude/frequency blocks, often ramping up from rest
(quasi-static, large-strain tests as they are published). This module turns them into the
bench's results table, one row per block, that :func:`droptower.validate` reads:

1. **Blocks** (:func:`find_blocks`): the imposed motion's cycles, found from its significant
   turning points (:func:`droptower.identify.cycles.turning_points`: reversals larger than the
   noise), grouped into plateaus of one amplitude and one frequency (each cycle within
   :data:`BLOCK_TOLERANCE` of the plateau's first). A block's cycles run from one upward
   crossing of its mean to the next; a cycle cut by the start of the record, by a change of
   amplitude or by the end of the record is not a whole cycle of the block and does not count
   (a crossing within a sample or so outside the record, where it starts or stops at one, is
   extrapolated). A whole cycle is evaluated only with samples on both sides of it (the
   smoothing's half window and a few more).
2. **Steady cycles**: the first ``settle_cycles`` of every block are never evaluated (the run-in
   after a change of amplitude: transients, first-cycle softening); of the rest the **last**
   ``cycles`` are (the steadiest). A block with no cycle left after the settling ones is
   skipped, and the notes say so.
3. **Evaluation**: :func:`droptower.servo.evaluate.evaluate_cycles`, the virtual bench's own
   evaluation (one-eighth-cycle Savitzky-Golay smoothing, whole cycles resampled, first-harmonic
   K' and K'' (the elastoslide paper, eq. 6), loss factor, loop work, relative damping psi,
   docs/theory.md#servo, #damping-measures), over the evaluated cycles at the block's frequency
   (from its upward crossings over all its whole cycles); and each evaluated cycle on its own,
   whose standard deviation over the cycles (ddof = 1; NaN for a single cycle) is the scatter
   reported beside each value (``storage_stiffness_std_nm_per_deg``, ``loss_factor_std``, ...).

A translational record (displacement and force: a mount, a bearing, a bushing) is evaluated in
its own units (fields named for it: ``storage_stiffness_n_per_m``, ``amplitude_mm``); with a
``lever_arm_m`` r it is read as the torsional record of a lever driven at radius r along its
arc, angle = x / r and torque = F r (so K'_torsional = K'_translational r^2 exactly), which is
what a map of the torsional drop tower is validated against.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Iterable

import numpy as np
import pandas as pd

from droptower.errors import DroptowerError, check_positive, finite_values
from droptower.servo.evaluate import MIN_SAMPLES_PER_CYCLE, evaluate_cycles, smoothing_window

if TYPE_CHECKING:
    from droptower.io.mapping import ServoSignals

#: Cycles evaluated per block (the last ones), as the virtual bench evaluates 5 (:func:`droptower.servo.run_grid`).
CYCLES = 5
#: Cycles at the start of every block that are never evaluated (the run-in after a change of amplitude).
SETTLE_CYCLES = 1
#: A cycle belongs to the current block while its amplitude and its frequency stay within this
#: fraction of the block's first cycle (the amplitude steps of a sweep are 20 % and more apart).
BLOCK_TOLERANCE = 0.08


@dataclass(frozen=True)
class RecordBlock:
    """One plateau of a record's imposed motion: whole cycles of one amplitude and frequency.

    index: 1-based, in the record's order; bounds_s: (n + 1,) times (s) of the upward
    crossings of the block's mean that bound its n whole cycles; amplitude_rad: the median
    half swing of its cycles (m for a translational record); frequency_hz: cycles over their
    duration between the inner crossings (all of them for a block of two cycles); mean_rad:
    the mean of the motion over its whole cycles.
    """

    index: int
    bounds_s: np.ndarray
    amplitude_rad: float
    frequency_hz: float
    mean_rad: float

    @property
    def n_cycles(self) -> int:
        """Whole cycles in the block."""
        return int(self.bounds_s.size - 1)


def _uniform_step(time_s: np.ndarray, file: str | Path | None) -> float:
    steps = np.diff(time_s)
    if time_s.size < 2 or not (steps > 0).all():
        bad = int(np.argmax(~(steps > 0))) + 1 if time_s.size >= 2 else 0
        raise DroptowerError(f"the time is not strictly increasing (sample {bad + 1})", file=file)
    step = float(np.median(steps))
    if np.max(np.abs(steps - step)) > 1e-6 * step + 1e-12:
        raise DroptowerError("the time is not uniformly sampled (the lab's smoothing needs a constant rate)", file=file)
    return float((time_s[-1] - time_s[0]) / (time_s.size - 1))


def _upward_crossings(y: np.ndarray, lo: int, hi: int, min_gap: float) -> np.ndarray:
    """Interpolated sample positions in [lo, hi) where ``y`` crosses 0 upwards, at least
    ``min_gap`` samples apart (noise near a crossing makes no second one)."""
    seg = y[lo:hi]
    idx = np.flatnonzero((seg[:-1] < 0) & (seg[1:] >= 0))
    found = [lo + i + (-seg[i]) / (seg[i + 1] - seg[i]) for i in idx]
    # a record that starts at a crossing, or stops within a sample or so of one (time stamps 0
    # to T - dt), has that crossing just outside its samples: extrapolated from the first/last two
    if lo == 0 and seg.size > 1 and seg[1] > seg[0] >= 0 and seg[0] <= seg[1] - seg[0]:
        found.insert(0, -seg[0] / (seg[1] - seg[0]))
    if hi == y.size and seg.size > 1 and seg[-2] < seg[-1] < 0 and -seg[-1] <= 1.5 * (seg[-1] - seg[-2]):
        found.append(y.size - 1 + (-seg[-1]) / (seg[-1] - seg[-2]))
    keep: list[float] = []
    for pos in found:
        if not keep or pos - keep[-1] >= min_gap:
            keep.append(pos)
    return np.asarray(keep)


def find_blocks(time_s: np.ndarray, motion: np.ndarray, *, tolerance: float = BLOCK_TOLERANCE,
                file: str | Path | None = None) -> list[RecordBlock]:
    """The amplitude/frequency plateaus of an imposed motion (module docstring, step 1).

    Parameters
    ----------
    time_s : (N,) array
        Uniform time base (s).
    motion : (N,) array
        The imposed angle (rad) or displacement (m).
    tolerance : float
        A cycle joins the current block while its amplitude and frequency stay within this
        fraction of the block's first cycle.
    file : path, optional
        Named in errors.

    Returns
    -------
    list of RecordBlock
        In the record's order; blocks of fewer than two whole cycles are left out.
    """
    from droptower.identify.cycles import cycles as max_to_max, turning_points

    t = finite_values(time_s, "time_s", file=file)
    x = finite_values(motion, "motion", file=file)
    dt = _uniform_step(t, file)
    tp = turning_points(x)
    if tp.size >= 2 and x[tp[0]] < x[tp[1]]:
        tp = tp[1:]  # maximum to maximum
    cyc = max_to_max(x, dt, tp)[::2]
    groups: list[tuple[int, int]] = []  # [i, j) into cyc
    i = 0
    while i < len(cyc):
        j = i + 1
        while (j < len(cyc) and abs(cyc[j].amplitude_rad / cyc[i].amplitude_rad - 1) <= tolerance
               and abs(cyc[j].frequency_hz / cyc[i].frequency_hz - 1) <= tolerance and cyc[j].start == cyc[j - 1].stop):
            j += 1
        groups.append((i, j))
        i = j
    out: list[RecordBlock] = []
    for i, j in groups:
        group = cyc[i:j]
        amplitude = float(np.median([c.amplitude_rad for c in group]))
        period = float(np.median([c.stop - c.start for c in group]))  # samples
        # the crossings before the group's first maximum and after its last minimum bound whole
        # cycles of the block too: search from the turning point before the first maximum to the
        # second after the last (the cycle test below keeps the transitions out)
        k0, k1 = np.searchsorted(tp, group[0].start), np.searchsorted(tp, group[-1].stop)
        lo = int(tp[k0 - 1]) if k0 >= 1 else 0
        hi = int(tp[k1 + 2]) + 1 if k1 + 2 < tp.size else x.size
        mean = float(np.mean(x[group[0].start:group[-1].stop]))
        up = _upward_crossings(x - mean, lo, hi, 0.5 * period)
        # whole cycles: crossing to crossing, of the block's amplitude and period, consecutive
        runs: list[list[int]] = [[]]
        for k in range(up.size - 1):
            a, b = int(math.ceil(up[k])), int(math.floor(up[k + 1])) + 1
            half_swing = 0.5 * float(np.ptp(x[a:b]))
            whole = (abs(half_swing / amplitude - 1) <= tolerance
                     and abs((up[k + 1] - up[k]) / period - 1) <= tolerance)
            if whole:
                runs[-1].append(k)
            elif runs[-1]:
                runs.append([])
        run = max(runs, key=len)
        if len(run) < 2:
            continue
        bounds = up[run[0]:run[-1] + 2]
        bounds_s = t[0] + bounds * dt
        # the frequency from the inner crossings: a crossing where the block meets the next (a kink
        # in the motion between two samples) is interpolated off by up to a fraction of a sample
        inner = bounds_s[1:-1] if bounds.size >= 4 else bounds_s
        frequency = (inner.size - 1) / (inner[-1] - inner[0])
        out.append(RecordBlock(len(out) + 1, bounds_s, amplitude, float(frequency),
                               float(np.mean(x[int(bounds[0]):int(bounds[-1])]))))
    return out


def evaluate_record(time_s: np.ndarray, motion: np.ndarray, load: np.ndarray, *, cycles: int = CYCLES,
                    settle_cycles: int = SETTLE_CYCLES, smooth: bool = True, units: str = "torsional",
                    file: str | Path | None = None, notes: list[str] | None = None) -> pd.DataFrame:
    """Evaluate one record block by block as the lab's bench software does (module docstring).

    Parameters
    ----------
    time_s : (N,) array
        Uniform time base (s).
    motion : (N,) array
        Imposed angle (rad), or displacement (m) with ``units="translational"``.
    load : (N,) array
        Measured torque (N*m), or force (N) with ``units="translational"``.
    cycles : int
        Cycles evaluated per block: the last ``cycles`` after the settling ones (fewer when
        the block is shorter; ``evaluated_cycles`` says how many).
    settle_cycles : int
        Cycles at the start of every block that are never evaluated.
    smooth : bool
        The one-eighth-cycle Savitzky-Golay smoothing of the lab's evaluation.
    units : {"torsional", "translational"}
        How the record reads; the table's fields are named for it.
    file : path, optional
        Named in errors and in the table's ``file`` column.
    notes : list, optional
        Gets a line for every block that could not be evaluated, and why.

    Returns
    -------
    DataFrame
        One row per evaluated block: ``file``, ``block``, ``block_start_s``, ``block_cycles``,
        ``evaluated_cycles``, ``amplitude_deg``/``_rad`` (half peak-to-peak of the evaluated
        cycles) with ``amplitude_std_deg``, ``frequency_hz``, every column of
        :meth:`~droptower.servo.evaluate.CycleEvaluation.records` (``storage_stiffness_nm_per_deg``,
        ``loss_factor``, ``relative_damping_psi``, ...) and the scatter over the evaluated
        cycles (``storage_stiffness_std_nm_per_deg``, ``loss_stiffness_std_nm_per_deg``,
        ``loss_factor_std``, ...). Translational records: the same fields named for them.
    """
    from droptower.io.fields import translate_table

    if int(cycles) != cycles or cycles < 1:
        raise DroptowerError(f"`cycles` must be a positive integer, got {cycles}", file=file)
    if int(settle_cycles) != settle_cycles or settle_cycles < 0:
        raise DroptowerError(f"`settle_cycles` must be a non-negative integer, got {settle_cycles}", file=file)
    names = ("angle", "torque") if units != "translational" else ("displacement", "force")
    t = finite_values(time_s, "time_s", file=file)
    x = finite_values(motion, names[0], file=file)
    y = finite_values(load, names[1], file=file)
    if not (t.shape == x.shape == y.shape) or x.ndim != 1:
        raise DroptowerError(f"time, {names[0]} and {names[1]} differ in length ({t.size}, {x.size}, {y.size})", file=file)
    blocks = find_blocks(t, x, file=file)
    if not blocks:
        raise DroptowerError(f"no block of at least two whole cycles of one amplitude and frequency in the {names[0]} "
                             f"({x.size} samples, {t[-1] - t[0]:.4g} s)", file=file)
    fs = 1.0 / _uniform_step(t, file)
    rows, skipped = [], []
    for block in blocks:
        f = block.frequency_hz
        where = f"block {block.index} ({block.n_cycles} cycles at {f:.4g} Hz)"
        if fs / f < MIN_SAMPLES_PER_CYCLE:
            skipped.append(f"{where}: {fs / f:.1f} samples per cycle, at least {MIN_SAMPLES_PER_CYCLE} needed")
            continue
        # the smoothing filter and the spline need a margin of samples outside the evaluated cycles
        window = smoothing_window(fs, f) if smooth else 0
        margin_s = (window // 2 + 5) / fs
        starts = block.bounds_s[:-1]
        usable = [k for k in range(settle_cycles, block.n_cycles)
                  if starts[k] - margin_s >= t[0] and starts[k] + 1.0 / f + margin_s <= t[-1]]
        if not usable:
            skipped.append(f"{where}: no whole cycle left after the {settle_cycles} settling cycle(s) (lower "
                           "`settle_cycles`, or the record ends too close to the block)")
            continue
        # the last `cycles` whole cycles whose window (with its margin) lies inside the record
        stop = usable[-1] + 1
        first = max(usable[0], stop - int(cycles))
        n = stop - first
        start_s = float(starts[first])
        ev = evaluate_cycles(t, x, y, f, start_s, n, smooth=smooth)
        single = [evaluate_cycles(t, x, y, f, start_s + k / f, 1, smooth=smooth) for k in range(n)] if n > 1 else []
        row = {"file": str(file) if file is not None else "", "block": block.index,
               "block_start_s": float(block.bounds_s[0]), "block_cycles": block.n_cycles,
               "amplitude_rad": ev.angle_amplitude_rad, "amplitude_deg": math.degrees(ev.angle_amplitude_rad)}
        row.update(ev.records()[0])

        def spread(values: list[float]) -> float:
            return float(np.std(values, ddof=1)) if len(values) > 1 else math.nan

        k1 = [e.storage_stiffness_nm_per_rad for e in single]
        k2 = [e.loss_stiffness_nm_per_rad for e in single]
        amp = [e.angle_amplitude_rad for e in single]
        row.update({
            "amplitude_std_rad": spread(amp), "amplitude_std_deg": math.degrees(spread(amp)),
            "storage_stiffness_std_nm_per_rad": spread(k1), "storage_stiffness_std_nm_per_deg": math.radians(spread(k1)),
            "loss_stiffness_std_nm_per_rad": spread(k2), "loss_stiffness_std_nm_per_deg": math.radians(spread(k2)),
            "loss_factor_std": spread([e.loss_factor for e in single]),
            "damping_work_std_j": spread([e.damping_work_j for e in single]),
            "first_cycle_start_s": start_s,
        })
        rows.append(row)
    if notes is not None:
        notes.extend(f"{file}: {text}" if file is not None else text for text in skipped)
    if not rows:
        raise DroptowerError(f"no block could be evaluated ({'; '.join(skipped)})", file=file)
    lead = ["file", "block", "amplitude_deg", "frequency_hz", "storage_stiffness_nm_per_deg",
            "loss_stiffness_nm_per_deg", "loss_factor", "storage_stiffness_std_nm_per_deg",
            "loss_stiffness_std_nm_per_deg", "loss_factor_std", "amplitude_std_deg", "evaluated_cycles",
            "block_cycles", "block_start_s", "first_cycle_start_s"]
    table = pd.DataFrame(rows)
    table = table[lead + [c for c in table.columns if c not in lead]]
    return translate_table(table, units)


def time_base_rate(sample_rate_hz: float | None, sample_interval_s: float | None) -> float | None:
    """The sample rate (Hz) of records without a time channel, from ``sample_rate_hz`` or
    ``sample_interval_s`` (s; at most one of the two, each > 0); None where neither is given."""
    if sample_rate_hz is not None and sample_interval_s is not None:
        raise DroptowerError("give `sample_rate_hz` or `sample_interval_s`, not both")
    check_positive(sample_rate_hz, "sample_rate_hz")
    check_positive(sample_interval_s, "sample_interval_s")
    return 1.0 / sample_interval_s if sample_interval_s is not None else sample_rate_hz


def read_servo_signals(path: str | Path, roles: dict[str, str] | None = None,
                       sample_rate_hz: float | None = None) -> "ServoSignals":
    """One raw servo record's imposed motion and measured load in SI, as the lab's bench reads it.

    Parameters
    ----------
    path : path
        A record in any format the readers take (:func:`droptower.io.read_any`).
    roles : dict, optional
        Channel role -> ``NAME[:UNIT]`` (:func:`droptower.io.map_servo_channels`).
    sample_rate_hz : float, optional
        The time base (Hz) of a record without a time channel (the time is then
        ``arange(n) / sample_rate_hz``, s); a record with one must run at this rate.

    Returns
    -------
    ServoSignals
        :func:`droptower.io.map_servo_channels`' signals (time s, motion rad or m, load N*m or
        N); a record without a time channel and no rate, or without a load channel, or whose own
        time base disagrees with the given rate, is a :class:`DroptowerError` naming ``path``.
    """
    from droptower.io import read_any
    from droptower.io.mapping import SERVO_KINDS, find_servo_roles, map_servo_channels

    record = read_any(path)
    _, specs = find_servo_roles(record, roles)
    motion_role = next((r for r in ("angle", "displacement") if r in specs), None)
    spec = specs.get(motion_role or "", "")
    own = record.channels.get(spec if spec in record.channels else spec.rsplit(":", 1)[0])
    timed = "time" in specs or (own is not None and own.time() is not None)
    if sample_rate_hz is None and not timed and motion_role is not None:
        # say which values give a time base before the mapping's generic message
        raise DroptowerError("no time channel; give `sample_rate_hz` or `sample_interval_s` (or name the time "
                             "channel with `roles={'time': 'NAME[:UNIT]'}`)", file=path)
    signals = map_servo_channels(record, roles, sample_rate_hz=sample_rate_hz)
    if sample_rate_hz is not None and timed and "time" not in (roles or {}):
        # a given rate and the file's own time base must agree: one of them would be silently wrong
        own_rate = 1.0 / _uniform_step(map_servo_channels(record, roles).time_s, path)
        if abs(own_rate / sample_rate_hz - 1.0) > 1e-6:
            raise DroptowerError(f"the file's time base runs at {own_rate:.6g} Hz, the given sample rate is "
                                 f"{sample_rate_hz:.6g} Hz; give neither `sample_rate_hz` nor `sample_interval_s` "
                                 "for a record with a time channel", file=path)
    if signals.load_si is None:
        role = SERVO_KINDS[signals.units][1]
        raise DroptowerError(f"no {role} channel found; name it with `roles={{'{role}': 'NAME[:UNIT]'}}` "
                             f"(the file has: {', '.join(repr(n) for n in record.channels)})", file=path)
    return signals


def _read_record(path: str | Path, roles: dict[str, str] | None, sample_rate_hz: float | None,
                 lever_arm_m: float | None):
    """(time_s, motion, load, units, notes) of one file, in SI (:func:`read_servo_signals`); a
    lever arm turns a translational record torsional (module docstring)."""
    signals = read_servo_signals(path, roles, sample_rate_hz)
    motion, load, units = signals.motion_si, signals.load_si, signals.units
    if lever_arm_m is not None:
        if units != "translational":
            raise DroptowerError("`lever_arm_m` turns a translational record (displacement, force) into a torsional "
                                 "one; this record is torsional already", file=path)
        motion, load, units = motion / lever_arm_m, load * lever_arm_m, "torsional"
    return signals.time_s, motion, load, units, list(signals.notes)


def evaluate_records(paths: str | Path | Iterable[str | Path], roles: dict[str, str] | None = None, *,
                     sample_rate_hz: float | None = None, sample_interval_s: float | None = None,
                     lever_arm_m: float | None = None, cycles: int = CYCLES, settle_cycles: int = SETTLE_CYCLES,
                     smooth: bool = True, notes: list[str] | None = None,
                     failures: list[DroptowerError] | None = None) -> pd.DataFrame:
    """Raw servo time records -> the bench's results table (K', K'', loss factor per block).

    Parameters
    ----------
    paths : path or iterable of paths
        Records in any format the readers take (:func:`droptower.io.read_any`): one file per
        test or one file with several amplitude/frequency blocks.
    roles : dict, optional
        Channel role -> ``NAME[:UNIT]`` (``time``, ``angle``, ``torque``, ``displacement``,
        ``force``); roles not given are found by name, units converted through pint
        (:func:`droptower.io.map_servo_channels`).
    sample_rate_hz, sample_interval_s : float, optional
        The time base of records without a time channel (give one of the two; Hz or s).
    lever_arm_m : float, optional
        Read translational records (displacement, force) as the torsional record of a lever
        of this radius (m): angle = x / r, torque = F r.
    cycles, settle_cycles, smooth
        As :func:`evaluate_record`.
    notes : list, optional
        Gets ``"<file>: <note>"`` for what was assumed in reading a file and for every block
        that could not be evaluated.
    failures : list, optional
        With a list, a file that cannot be read or evaluated is appended to it (its
        :class:`~droptower.errors.DroptowerError`, naming the file) and the others go on;
        without one, the first such file raises.

    Returns
    -------
    DataFrame
        The rows of :func:`evaluate_record` of every file, in order; readable as it is by
        :func:`droptower.validate` (``servo_results``) when torsional.

    Examples
    --------
    >>> from droptower.servo import evaluate_records
    >>> table = evaluate_records(["sweep.csv"], sample_rate_hz=2048.0)  # doctest: +SKIP
    >>> table[["amplitude_deg", "frequency_hz", "storage_stiffness_nm_per_deg", "loss_factor"]]  # doctest: +SKIP
    """
    rate = time_base_rate(sample_rate_hz, sample_interval_s)
    check_positive(lever_arm_m, "lever_arm_m")
    paths = [Path(paths)] if isinstance(paths, (str, Path)) else [Path(p) for p in paths]
    if not paths:
        raise DroptowerError("give at least one record")
    tables: list[pd.DataFrame] = []
    kinds: dict[str, Path] = {}
    for path in paths:
        try:
            time, motion, load, units, read_notes = _read_record(path, roles, rate, lever_arm_m)
            if kinds and units not in kinds:
                other, first = next(iter(kinds.items()))
                raise DroptowerError(f"a {units} record among {other} ones ({first}): evaluate records of one kind "
                                     "together (or give `lever_arm_m` to read translational ones as torsional)",
                                     file=path)
            kinds.setdefault(units, path)
            if notes is not None:
                notes.extend(f"{path}: {text}" for text in read_notes)
            tables.append(evaluate_record(time, motion, load, cycles=cycles, settle_cycles=settle_cycles,
                                          smooth=smooth, units=units, file=path, notes=notes))
        except DroptowerError as exc:
            if failures is None:
                raise exc.with_file(path) from None
            failures.append(exc.with_file(path))
    if not tables:
        return pd.DataFrame()
    return pd.concat(tables, ignore_index=True)
