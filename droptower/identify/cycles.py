"""Load cycles in an imposed angle history: turning points, cycles, steady blocks, first harmonic.

The staged identifications need to know where the data hold steady sine cycles (the elastoslide paper's
initial loading curve from loop peaks, Heine & Plagemann's (2014) per-amplitude levels, Scheiblegger et al.'s (2013) dynamic
stiffness and loss angle at a layout frequency). Cycles are found from the angle alone, the
way a test engineer reads a record: significant turning points (reversals larger than the
noise), a cycle from one maximum to the next, blocks of consecutive cycles of the same
amplitude and frequency.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from droptower.errors import DroptowerError
from droptower.servo.evaluate import CycleEvaluation, evaluate_cycles


def noise_std(x: np.ndarray) -> float:
    """Robust estimate of white measurement noise in ``x`` (same unit), from second differences.

    For a densely sampled smooth signal the second difference is noise only; its variance is
    6 sigma^2. The median absolute deviation makes the estimate immune to the signal's kinks.
    """
    if x.size < 5:
        return 0.0
    d2 = np.diff(x, 2)
    return float(1.4826 * np.median(np.abs(d2 - np.median(d2))) / np.sqrt(6.0))


def turning_points(x: np.ndarray, threshold: float | None = None) -> np.ndarray:
    """Indices of the significant reversals of ``x`` (alternating maxima and minima).

    A reversal counts when ``x`` comes back from its running extreme by more than
    ``threshold`` (default: 6 noise standard deviations plus 0.2 % of the range), so noise and
    tiny wiggles do not make cycles.
    """
    x = np.asarray(x, dtype=float)
    if x.size < 3:
        return np.empty(0, dtype=np.int64)
    if threshold is None:
        threshold = 6.0 * noise_std(x) + 2e-3 * float(np.ptp(x))
    if threshold <= 0.0:
        threshold = np.finfo(float).tiny
    # zig-zag with hysteresis: the direction is set once x has left its start by the
    # threshold; a running extreme becomes a turning point when x has come back by it
    points: list[int] = []
    i_hi = i_lo = 0
    direction = 0  # +1 rising (tracking a maximum), -1 falling (tracking a minimum)
    for i in range(1, x.size):
        v = x[i]
        if direction == 0:
            if v > x[i_hi]:
                i_hi = i
            if v < x[i_lo]:
                i_lo = i
            if v - x[0] > threshold:
                direction = 1
            elif x[0] - v > threshold:
                direction = -1
        elif direction == 1:
            if v > x[i_hi]:
                i_hi = i
            elif x[i_hi] - v > threshold:
                points.append(i_hi)
                direction, i_lo = -1, i
        else:
            if v < x[i_lo]:
                i_lo = i
            elif v - x[i_lo] > threshold:
                points.append(i_lo)
                direction, i_hi = 1, i
    return np.asarray(points, dtype=np.int64)


@dataclass(frozen=True)
class Cycle:
    """One load cycle from a turning point to the next of the same kind.

    start, stop: sample indices (stop exclusive, the next turning point of the same kind);
    amplitude_rad: half the swing; frequency_hz: 1 / duration; mean_rad: mean angle.
    """

    start: int
    stop: int
    amplitude_rad: float
    frequency_hz: float
    mean_rad: float


def cycles(x: np.ndarray, dt_s: float, points: np.ndarray | None = None) -> list[Cycle]:
    """Full cycles of ``x`` from maximum to maximum (and minimum to minimum, interleaved)."""
    tp = turning_points(x) if points is None else points
    out = []
    for a, b, c in zip(tp[:-2], tp[1:-1], tp[2:]):
        out.append(Cycle(int(a), int(c), 0.25 * (abs(x[a] - x[b]) + abs(x[c] - x[b])),
                         1.0 / ((c - a) * dt_s), float(np.mean(x[a:c]))))
    return out


def local_amplitude_frequency(x: np.ndarray, dt_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Per sample: amplitude (rad) and frequency (Hz) of the half cycle it lies in.

    A half cycle runs between consecutive turning points; its amplitude is half its swing, its
    frequency 1 / (2 * its duration). Samples before the first and after the last turning
    point take the values of the nearest half cycle.
    """
    tp = turning_points(x)
    n = x.size
    if tp.size < 2:
        amp = 0.5 * float(np.ptp(x))
        return np.full(n, amp), np.full(n, 1.0 / (2.0 * n * dt_s))
    amp = 0.5 * np.abs(np.diff(x[tp]))
    freq = 1.0 / (2.0 * np.diff(tp) * dt_s)
    which = np.clip(np.searchsorted(tp, np.arange(n), side="right") - 1, 0, amp.size - 1)
    return amp[which], freq[which]


@dataclass(frozen=True)
class Block:
    """Consecutive cycles of one amplitude and frequency (a steady sine stretch).

    start, stop: sample indices; amplitude_rad: median half swing of its cycles after the
    first; frequency_hz: from the interpolated upward crossings of its mean angle;
    evaluation_start_s, evaluation_cycles: whole cycles from the second crossing on, the
    first cycle (a transient) and the last (a margin) left out.
    """

    start: int
    stop: int
    n_cycles: int
    amplitude_rad: float
    frequency_hz: float
    mean_rad: float
    evaluation_start_s: float
    evaluation_cycles: int

    @property
    def first_cycle_stop(self) -> int:
        """Sample index where the cycles after the first begin."""
        return self.start + int(round((self.stop - self.start) / self.n_cycles))


def _upward_crossings(y: np.ndarray, min_gap: int) -> np.ndarray:
    """Interpolated sample positions where ``y`` crosses 0 upwards, at least ``min_gap`` apart."""
    idx = np.flatnonzero((y[:-1] < 0) & (y[1:] >= 0))
    keep: list[float] = []
    for i in idx:
        pos = i + (-y[i]) / (y[i + 1] - y[i])
        if not keep or pos - keep[-1] >= min_gap:
            keep.append(pos)
    return np.asarray(keep)


def blocks(x: np.ndarray, dt_s: float, rel_tol: float = 0.08, min_cycles: int = 4) -> list[Block]:
    """Stretches of at least ``min_cycles`` maximum-to-maximum cycles whose amplitude and
    frequency stay within ``rel_tol`` of the stretch's first cycle."""
    tp = turning_points(x)
    if tp.size >= 2 and x[tp[0]] < x[tp[1]]:
        tp = tp[1:]  # start at a maximum so that cycles are maximum to maximum
    cyc = cycles(x, dt_s, tp)[::2]
    out: list[Block] = []
    i = 0
    while i < len(cyc):
        j = i + 1
        while (j < len(cyc) and abs(cyc[j].amplitude_rad / cyc[i].amplitude_rad - 1) <= rel_tol
               and abs(cyc[j].frequency_hz / cyc[i].frequency_hz - 1) <= rel_tol
               and cyc[j].start == cyc[j - 1].stop):
            j += 1
        if j - i >= min_cycles:
            group = cyc[i:j]
            a, b = group[0].start, group[-1].stop
            mean = float(np.mean(x[a:b]))
            period = (b - a) / (j - i)
            up = a + _upward_crossings(x[a:b] - mean, int(0.5 * period))
            if up.size >= 4:
                freq = (up.size - 1) / ((up[-1] - up[0]) * dt_s)
                out.append(Block(a, b, j - i, float(np.median([c.amplitude_rad for c in group[1:]])), float(freq),
                                 mean, float(up[1] * dt_s), int(up.size - 3)))
        i = j
    return out


def evaluate_block(angle_rad: np.ndarray, torque_nm: np.ndarray, dt_s: float, block: Block) -> CycleEvaluation | None:
    """The servo lab's evaluation (K', K'', loop work; :func:`droptower.servo.evaluate_cycles`)
    of a block's whole cycles after its first, or None if too coarsely sampled for it."""
    time = np.arange(angle_rad.size) * dt_s
    try:
        return evaluate_cycles(time, angle_rad, torque_nm, block.frequency_hz, block.evaluation_start_s,
                               block.evaluation_cycles)
    except DroptowerError:
        return None
