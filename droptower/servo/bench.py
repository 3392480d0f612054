"""The virtual servo-hydraulic bench: drive a coupling through a grid of sine tests.

A grid point is one sine test (:func:`droptower.servo.histories.sine`) at an amplitude and a
frequency about the mean angle that carries the requested preload torque. All amplitudes of
one frequency share one history length and run as one batch (``Coupling.simulate`` with a
batch row per amplitude); the frequencies run one after another.

Like a real bench, the coupling runs on a fine time step and the record is sampled at the
acquisition rate ``sample_rate_hz`` (2048 Hz on the paper's bench, docs/theory.md#rig). The fine step
matters: the kernels see the angle linear between steps, so a dashpot reads the rate of the
last step, half a step h late, which shifts K' by about K'' * omega * h / 2 (at h = 1/2048 s
and 30 Hz, 4.6 % of K''). The fine rate is at least ``simulation_rate_hz`` (default the
drop tower's 38.4 kHz) and at least :data:`MIN_STEPS_PER_CYCLE` steps per cycle, so that
shift stays below pi / 4096 = 0.08 % of K'' at every frequency (the cost per test stays
small: a fast test is short), rounded up to a whole multiple of the sample rate.

The preload is a torque: the mean angle is found by secant iterations on the mean torque of
the evaluated cycles (the steady-state mean torque), each iteration one batched run. Without
preload the test oscillates about the unloaded position (angle 0), as on a real bench; the
mean torque it then carries is reported (``mean_torque_nm``). As a lab sets a preload, the
bench first turns the coupling quasi-statically to the mean angle (a smooth ramp over
``preload_ramp_s``) and holds it for ``preload_hold_s`` before the sine starts: the coupling's
rate-dependent parts relax and a filled rubber's network re-forms about the held twist (the
drop tower's preload is set the same way, :mod:`droptower.rig.preload`; docs/theory.md#filler-network).
The ramp and the hold run on coarse steps (exact at rest) and are not part of the record.

:func:`run_records` gives the time records behind the table (at the acquisition rate) for
users who want the raw signals.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator, Sequence

import numpy as np
import pandas as pd

from droptower.errors import DroptowerError
from droptower.limits import require_memory, require_steps
from droptower.rates import RIG_SAMPLE_RATE_HZ, SERVO_SAMPLE_RATE_HZ
from droptower.rheology import Coupling, load_coupling
from droptower.rig.config import PRELOAD_HOLD_S, PRELOAD_RAMP_S
from droptower.servo import histories
from droptower.servo.evaluate import MIN_SAMPLES_PER_CYCLE, CycleEvaluation, evaluate_cycles

#: Mean torque within this fraction of max(|preload|, torque amplitude) counts as reached.
PRELOAD_TOLERANCE = 1e-4
PRELOAD_ITERATIONS = 12
#: The fewest simulation steps per cycle of the excitation (see the module docstring).
MIN_STEPS_PER_CYCLE = 4096
#: Amplitudes a bench can drive (rad): 1e-6 deg to 90 deg; preloads (N*m) up to 1 MN*m.
AMPLITUDE_RANGE_RAD = (math.radians(1e-6), math.radians(90.0))
MAX_PRELOAD_NM = 1e6
#: Samples per simulate() call and batch row bound the memory of long, finely stepped runs.
CHUNK_SAMPLES = 1 << 21
#: The preload is set like the drop tower's (droptower.rig.preload), with its ramp and hold
#: (droptower.rig.config.PRELOAD_RAMP_S, PRELOAD_HOLD_S: one definition): a quasi-static ramp to
#: the mean angle, then a hold long against the slowest relaxation of the reference coupling.
PRELOAD_RAMP_STEPS = 200
PRELOAD_HOLD_STEPS = 600


@dataclass(frozen=True)
class BenchResult:
    """``table``: one row per grid point (see :func:`run_grid`); ``evaluations``: the
    :class:`~droptower.servo.evaluate.CycleEvaluation` of each row (loops for plots)."""

    table: pd.DataFrame
    evaluations: list[CycleEvaluation]


@dataclass(frozen=True)
class BenchRecord:
    """The time record of one grid point, sampled at the acquisition rate (SI).

    amplitude_rad, frequency_hz, preload_nm: the commanded test; offset_rad: the mean angle
    found for the preload; time_s, angle_rad, torque_nm (N,): the whole test (offset ramp,
    run-in, evaluated cycles, tail), as a bench's data acquisition records it. With a preload
    the offset segment is a rest at the mean angle, which the unrecorded ramp and hold set.
    """

    amplitude_rad: float
    frequency_hz: float
    preload_nm: float
    offset_rad: float
    time_s: np.ndarray = field(repr=False)
    angle_rad: np.ndarray = field(repr=False)
    torque_nm: np.ndarray = field(repr=False)


def _as_coupling(coupling: Coupling | str | Path) -> Coupling:
    c = coupling if isinstance(coupling, Coupling) else load_coupling(coupling)
    if c.n_sets != 1:
        raise DroptowerError(f"the servo bench drives one parameter set at a time; this coupling has {c.n_sets}")
    return c


def _positive_list(values: Sequence[float], what: str, unit: str) -> np.ndarray:
    arr = np.atleast_1d(np.asarray(values, dtype=float))
    if arr.ndim != 1 or arr.size == 0:
        raise DroptowerError(f"give at least one {what}")
    if not np.all(np.isfinite(arr) & (arr > 0)):
        raise DroptowerError(f"every {what} must be positive and finite, got {arr.tolist()} {unit}")
    return arr


def _set_preload(coupling: Coupling, offsets: np.ndarray, ramp_s: float, hold_s: float):
    """A fresh state (B rows) after the quasi-static ramp to ``offsets`` (rad) and the hold there."""
    state = coupling.new_state(offsets.size)
    s = np.arange(1, PRELOAD_RAMP_STEPS + 1) / PRELOAD_RAMP_STEPS
    smooth = s * s * (3.0 - 2.0 * s)  # smoothstep: the ramp starts and ends at rest
    coupling.simulate(offsets[:, None] * smooth[None, :], ramp_s / PRELOAD_RAMP_STEPS, state, record_energy=False)
    if hold_s > 0.0:
        coupling.simulate(np.repeat(offsets[:, None], PRELOAD_HOLD_STEPS, axis=1), hold_s / PRELOAD_HOLD_STEPS, state,
                          record_energy=False)
    return state


def _drive(coupling: Coupling, unit_sine: np.ndarray, unit_ramp: np.ndarray, amplitudes: np.ndarray,
           offsets: np.ndarray, dt_s: float, substeps: int, preload: tuple[float, float] | None = None) -> np.ndarray:
    """Torque (B, N_lab) at every ``substeps``-th sample of the histories
    offset_b * unit_ramp + amplitude_b * unit_sine (``sine`` is linear in both), in chunks.
    ``preload`` (ramp_s, hold_s): the offsets are set and held first (:func:`_set_preload`) and
    ``unit_ramp`` must then be 1 throughout."""
    batch, n = amplitudes.size, unit_sine.size
    chunk = max(substeps, (CHUNK_SAMPLES // batch) // substeps * substeps)
    out = []
    state = coupling.new_state(batch) if preload is None else _set_preload(coupling, offsets, *preload)
    for lo in range(0, n, chunk):
        hi = min(n, lo + chunk)
        angle = offsets[:, None] * unit_ramp[None, lo:hi] + amplitudes[:, None] * unit_sine[None, lo:hi]
        torque = coupling.simulate(angle, dt_s, state).torque_nm
        out.append(torque.reshape(batch, -1)[:, ::substeps])
    return np.concatenate(out, axis=1)


def _run_frequency(coupling: Coupling, frequency_hz: float, amplitudes: np.ndarray, preload_nm: float,
                   sample_rate_hz: float, substeps: int, cycles: int, run_in_cycles: int, ramp_cycles: int,
                   smooth: bool, preload_ramp_s: float = PRELOAD_RAMP_S, preload_hold_s: float = PRELOAD_HOLD_S
                   ) -> tuple[np.ndarray, list[CycleEvaluation], np.ndarray, np.ndarray, np.ndarray]:
    """Offsets (rad), evaluations and records (time (N,), angle and torque (B, N) at the sample
    rate) of the amplitudes at one frequency, preload reached (set and held first)."""
    fine = sample_rate_hz * substeps
    kw = dict(run_in_cycles=run_in_cycles, cycles=cycles, ramp_cycles=ramp_cycles)
    unit_sine = histories.sine(frequency_hz, 1.0, fine, **kw)
    # with a preload the mean angle is set and held before the sine (_set_preload): the history's
    # offset segment is then a rest at the mean angle
    preload = None if preload_nm == 0.0 else (preload_ramp_s, preload_hold_s)
    unit_ramp = (histories.sine(frequency_hz, 0.0, fine, offset_rad=1.0, **kw).angle_rad if preload is None
                 else np.ones(unit_sine.angle_rad.size))
    seg = unit_sine.evaluation_segments[0]
    time_lab = unit_sine.time_s[::substeps]

    def run(rows: np.ndarray, offsets: np.ndarray) -> tuple[list[CycleEvaluation], np.ndarray, np.ndarray]:
        torque = _drive(coupling, unit_sine.angle_rad, unit_ramp, amplitudes[rows], offsets, 1.0 / fine, substeps,
                        preload)
        angle = offsets[:, None] * unit_ramp[None, ::substeps] + amplitudes[rows, None] * unit_sine.angle_rad[None, ::substeps]
        return [evaluate_cycles(time_lab, angle[i], torque[i], frequency_hz, seg.start_s, seg.cycles, smooth=smooth)
                for i in range(rows.size)], angle, torque

    rows = np.arange(amplitudes.size)
    offsets = np.zeros(amplitudes.size)
    evals, angle, torque = run(rows, offsets)

    def residual(ev: list[CycleEvaluation]) -> tuple[np.ndarray, np.ndarray]:
        r = np.array([e.mean_torque_nm for e in ev]) - preload_nm
        tol = PRELOAD_TOLERANCE * np.maximum(abs(preload_nm), [e.torque_amplitude_nm for e in ev])
        return r, np.abs(r) <= tol

    res, ok = residual(evals)
    if preload_nm == 0.0:  # no preload: the test oscillates about the unloaded position
        ok[:] = True
    # first step: Newton with the dynamic storage stiffness; then secant on the mean torque
    slope = np.array([e.storage_stiffness_nm_per_rad for e in evals])
    prev_off, prev_res = offsets.copy(), res.copy()
    for _ in range(PRELOAD_ITERATIONS):
        todo = np.flatnonzero(~ok)
        if not todo.size:
            break
        if not np.all(np.isfinite(slope[todo]) & (slope[todo] > 0)):
            raise DroptowerError(f"cannot reach the preload of {preload_nm:g} N*m at {frequency_hz:g} Hz: "
                                 f"the mean torque does not rise with the mean angle")
        new_off = offsets[todo] - res[todo] / slope[todo]
        new_evals, angle[todo], torque[todo] = run(todo, new_off)
        new_res, new_ok = residual(new_evals)
        prev_off[todo], prev_res[todo] = offsets[todo], res[todo]
        offsets[todo], res[todo], ok[todo] = new_off, new_res, new_ok
        for j, i in enumerate(todo):
            evals[i] = new_evals[j]
        with np.errstate(invalid="ignore", divide="ignore"):
            slope[todo] = (res[todo] - prev_res[todo]) / (offsets[todo] - prev_off[todo])
    if not np.all(ok):
        bad = np.flatnonzero(~ok)[0]
        raise DroptowerError(f"preload of {preload_nm:g} N*m not reached at {math.degrees(amplitudes[bad]):g} deg, "
                             f"{frequency_hz:g} Hz after {PRELOAD_ITERATIONS} iterations "
                             f"(mean torque {evals[bad].mean_torque_nm:g} N*m)")
    return offsets, evals, time_lab, angle, torque


def _check_size(coupling: Coupling, batch: int, freqs: np.ndarray, preload_nm: float, sample_rate_hz: float,
                simulation_rate_hz: float, n_cycles: float) -> None:
    """Refuse a grid whose records (memory) or coupling steps (run time) are out of reach, before
    anything is allocated: the lowest frequency has the longest records."""
    f = float(freqs.min())
    fine = max(simulation_rate_hz, MIN_STEPS_PER_CYCLE * f)
    substeps = max(1, math.ceil(fine / sample_rate_hz - 1e-9))
    n_fine = n_cycles / f * sample_rate_hz * substeps
    n_lab = n_fine / substeps
    # fine: time, unit sine, unit ramp, one chunk of angles per instance; lab: time, angle,
    # torque and the evaluation's smoothed copies per instance; the coupling's state
    nbytes = 8.0 * (3 * n_fine + batch * (min(n_fine, CHUNK_SAMPLES) + 6 * n_lab + coupling.n_state))
    what = f"the servo run at {f:g} Hz ({n_cycles:g} cycles of {1 / f:.3g} s, {batch} amplitude(s))"
    split = "raise the lowest `frequencies_hz`, lower `cycles` or `sample_rate_hz`, or run fewer amplitudes at once"
    require_memory(nbytes, what, split)
    iterations = 1 + (PRELOAD_ITERATIONS if preload_nm != 0.0 else 0)
    require_steps(batch * iterations * float(np.sum(n_cycles / freqs * np.maximum(simulation_rate_hz,
                                                                              MIN_STEPS_PER_CYCLE * freqs))),
                  f"the servo grid ({batch} amplitude(s) x {freqs.size} frequencies)", split)


def _grid(coupling: Coupling | str | Path, amplitudes_rad: Sequence[float], frequencies_hz: Sequence[float],
          preload_nm: float, sample_rate_hz: float, cycles: int, run_in_cycles: int, ramp_cycles: int,
          simulation_rate_hz: float, smooth: bool, preload_hold_s: float = PRELOAD_HOLD_S
          ) -> Iterator[tuple[BenchRecord, CycleEvaluation, float]]:
    """Check the grid, then run it frequency by frequency: per grid point its record, its
    evaluation and the fine simulation rate (Hz) it ran with."""
    c = _as_coupling(coupling)
    amps = _positive_list(amplitudes_rad, "amplitude", "rad")
    # beyond these the torque under- or overflows and the evaluation blames the record, not the value
    if not np.all((amps >= AMPLITUDE_RANGE_RAD[0]) & (amps <= AMPLITUDE_RANGE_RAD[1])):
        raise DroptowerError(f"every amplitude must lie within {math.degrees(AMPLITUDE_RANGE_RAD[0]):g}-"
                             f"{math.degrees(AMPLITUDE_RANGE_RAD[1]):g} deg, got "
                             f"{', '.join(f'{math.degrees(a):g}' for a in amps)} deg")
    freqs = _positive_list(frequencies_hz, "frequency", "Hz")
    if not (math.isfinite(preload_nm)):
        raise DroptowerError(f"preload must be finite, got {preload_nm}")
    if abs(preload_nm) > MAX_PRELOAD_NM:
        raise DroptowerError(f"preload {preload_nm:g} N*m is beyond +-{MAX_PRELOAD_NM:g} N*m")
    if not (math.isfinite(preload_hold_s) and preload_hold_s >= 0.0):
        raise DroptowerError(f"the preload's hold must be a finite, non-negative time, got {preload_hold_s} s")
    if not (math.isfinite(sample_rate_hz) and sample_rate_hz > 0 and math.isfinite(simulation_rate_hz)
            and simulation_rate_hz > 0):
        raise DroptowerError("sample rate and simulation rate must be positive")
    if sample_rate_hz / freqs.max() < MIN_SAMPLES_PER_CYCLE:
        raise DroptowerError(f"sample rate {sample_rate_hz:g} Hz is too coarse for {freqs.max():g} Hz: "
                             f"{sample_rate_hz / freqs.max():.1f} samples per cycle, at least "
                             f"{MIN_SAMPLES_PER_CYCLE} needed")
    if int(cycles) != cycles or cycles < 1 or int(run_in_cycles) != run_in_cycles or run_in_cycles < 1:
        raise DroptowerError(f"cycles ({cycles}) and run-in cycles ({run_in_cycles}) must be positive integers")

    _check_size(c, amps.size, freqs, preload_nm, sample_rate_hz, simulation_rate_hz,
                ramp_cycles + run_in_cycles + cycles + 0.5)
    for f in freqs:
        fine = max(simulation_rate_hz, MIN_STEPS_PER_CYCLE * f)
        substeps = max(1, math.ceil(fine / sample_rate_hz - 1e-9))
        offsets, evals, time_s, angle, torque = _run_frequency(
            c, float(f), amps, float(preload_nm), float(sample_rate_hz), substeps, int(cycles), int(run_in_cycles),
            int(ramp_cycles), smooth, PRELOAD_RAMP_S, float(preload_hold_s))
        for i, (a, off, ev) in enumerate(zip(amps, offsets, evals)):
            record = BenchRecord(amplitude_rad=float(a), frequency_hz=float(f), preload_nm=float(preload_nm),
                                 offset_rad=float(off), time_s=time_s, angle_rad=angle[i], torque_nm=torque[i])
            yield record, ev, float(sample_rate_hz * substeps)


def run_bench(coupling: Coupling | str | Path, amplitudes_rad: Sequence[float], frequencies_hz: Sequence[float],
              preload_nm: float = 0.0, sample_rate_hz: float = SERVO_SAMPLE_RATE_HZ, cycles: int = 5, *, run_in_cycles: int = 5,
              ramp_cycles: int = 2, simulation_rate_hz: float = RIG_SAMPLE_RATE_HZ, smooth: bool = True,
              preload_hold_s: float = PRELOAD_HOLD_S) -> BenchResult:
    """Run the grid amplitudes x frequencies on the bench; see :func:`run_grid`."""
    rows, evaluations = [], []
    for record, ev, simulation_rate in _grid(coupling, amplitudes_rad, frequencies_hz, preload_nm, sample_rate_hz,
                                             cycles, run_in_cycles, ramp_cycles, simulation_rate_hz, smooth,
                                             preload_hold_s):
        a, off = record.amplitude_rad, record.offset_rad
        # 12 digits: an amplitude given as 1.5 deg reads back as 1.5, not 1.5000000000000002
        rec = {"amplitude_rad": a, "amplitude_deg": float(f"{math.degrees(a):.12g}"),
               "preload_nm": record.preload_nm, "offset_rad": off, "offset_deg": math.degrees(off)}
        rec.update(ev.records()[0])
        rec["simulation_rate_hz"] = simulation_rate
        rows.append(rec)
        evaluations.append(ev)
    table = pd.DataFrame(rows)
    lead = ["amplitude_deg", "frequency_hz", "preload_nm"]
    table = table[lead + [col for col in table.columns if col not in lead]]
    return BenchResult(table, evaluations)


def run_records(coupling: Coupling | str | Path, amplitudes_rad: Sequence[float], frequencies_hz: Sequence[float],
                preload_nm: float = 0.0, sample_rate_hz: float = SERVO_SAMPLE_RATE_HZ, cycles: int = 5, *,
                run_in_cycles: int = 5, ramp_cycles: int = 2, simulation_rate_hz: float = RIG_SAMPLE_RATE_HZ,
                preload_hold_s: float = PRELOAD_HOLD_S) -> list[BenchRecord]:
    """The time records of the grid amplitudes x frequencies (frequency-major, as the rows of
    :func:`run_grid`), sampled at ``sample_rate_hz``: the raw signals behind the table, for
    users who evaluate, identify or plot them themselves. Same arguments and the same runs
    (fine simulation step, preload found by iteration) as :func:`run_grid`.
    """
    return [record for record, _, _ in _grid(coupling, amplitudes_rad, frequencies_hz, preload_nm, sample_rate_hz,
                                             cycles, run_in_cycles, ramp_cycles, simulation_rate_hz, smooth=True,
                                             preload_hold_s=preload_hold_s)]


def run_grid(coupling: Coupling | str | Path, amplitudes_rad: Sequence[float], frequencies_hz: Sequence[float],
             preload_nm: float = 0.0, sample_rate_hz: float = SERVO_SAMPLE_RATE_HZ, cycles: int = 5, *, run_in_cycles: int = 5,
             ramp_cycles: int = 2, simulation_rate_hz: float = RIG_SAMPLE_RATE_HZ, smooth: bool = True,
             preload_hold_s: float = PRELOAD_HOLD_S) -> pd.DataFrame:
    """Servo-bench results on the grid ``amplitudes_rad`` x ``frequencies_hz``, one row each.

    ``coupling``: a :class:`~droptower.Coupling`, a coupling file or a preset name.
    ``preload_nm``: mean torque (N*m) about which every test oscillates; the mean angle is set
    by a quasi-static ramp and held ``preload_hold_s`` (s) before the sine starts (as the drop
    tower sets its preload).
    ``sample_rate_hz``: acquisition rate of the record that is evaluated (at least 20 samples
    per cycle at the highest frequency); ``simulation_rate_hz``: the fine step the coupling
    is driven with at least (raised to :data:`MIN_STEPS_PER_CYCLE` steps per cycle, rounded up
    to a multiple of the sample rate; reported per row).
    ``cycles`` evaluated cycles follow ``run_in_cycles`` discarded ones; the amplitude rises
    over the first ``ramp_cycles``.

    Columns (SI plus degree variants, unit in every name): ``amplitude_deg``,
    ``amplitude_rad`` (commanded), ``frequency_hz``, ``preload_nm``, ``offset_rad/_deg``
    (mean angle found for the preload), ``storage_stiffness_nm_per_rad/_deg``,
    ``loss_stiffness_nm_per_rad/_deg``, ``dynamic_stiffness_nm_per_rad/_deg``,
    ``loss_angle_rad/_deg``, ``loss_factor``, ``damping_work_j`` (loop area per cycle),
    ``elastic_work_j``, ``relative_damping_psi``, ``drop_tower_equivalent_damping_ratio``,
    ``angle_amplitude_rad/_deg``, ``torque_amplitude_nm`` (half peak-to-peak, measured),
    ``mean_angle_rad/_deg``, ``mean_torque_nm``, ``steady_state_deviation``,
    ``smoothing_window_samples``, ``sample_rate_hz``, ``simulation_rate_hz`` and more.
    """
    return run_bench(coupling, amplitudes_rad, frequencies_hz, preload_nm, sample_rate_hz, cycles,
                     run_in_cycles=run_in_cycles, ramp_cycles=ramp_cycles, simulation_rate_hz=simulation_rate_hz,
                     smooth=smooth, preload_hold_s=preload_hold_s).table
