"""Time stamps as lab software prints them: a constant sample rate behind rounded stamps.

Lab exports print time with a fixed number of decimals or significant digits (``0.0010``,
``0.0020`` at 1024 Hz), so the steps between stamps differ by up to one printed digit although
the rate is constant. :func:`regular_time` recognises that case: some uniform time base lies
within half a printed digit of every stamp of the whole record. Its rate is a whole number of
Hz if one is consistent with every stamp, else the middle of the consistent rates (two small
linear programs over start and step); the stamps are replaced by the uniform ones, with a note
saying so. Stamps stored as float32 are rounded the same way, to 24 bits. Steps that rounding
does not explain but agree to 0.1 % are kept as they are; any other time base is truly
irregular and refused with one line naming the file.
"""
from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from droptower.errors import DroptowerError

#: Steps that differ from their mean by at most this (relative) are uniform as they are
#: (float round-off of computed stamps).
EXACT = 1e-9
#: Largest deviation of one time step from the mean step (relative) still taken as uniform
#: when rounding to the printed precision does not explain it.
DT_TOLERANCE = 1e-3
#: Most decimals looked for in printed time stamps (1 ns), and most significant digits (more
#: come near a double's own precision, where every value looks exactly printed).
MAX_DECIMALS = 9
MAX_DIGITS = 12


def _exact(scaled: np.ndarray) -> bool:
    """Every value a whole number, up to the few ulps of a stamp parsed from text."""
    slack = 1e-9 + 8 * np.finfo(float).eps * float(np.max(np.abs(scaled)))
    return float(np.max(np.abs(scaled - np.round(scaled)))) <= slack


def printed_precision(time_s: np.ndarray) -> list[tuple[str, np.ndarray]]:
    """How the stamps may have been printed: (description, each stamp's last digit in s), for
    the fewest fixed decimals (0..9) and the fewest significant digits (1..12) that print
    every stamp exactly, and float32 storage (a binary rounding of the same kind); any may be
    absent."""
    return list(_precisions(np.asarray(time_s, dtype=np.float64)))


def _precisions(t: np.ndarray) -> Iterator[tuple[str, np.ndarray]]:
    """:func:`printed_precision`, one at a time (the first that explains the stamps ends the search)."""
    decimals = next((d for d in range(MAX_DECIMALS + 1) if _exact(t * 10.0 ** d)), None)
    if decimals is not None:
        yield f"{decimals} decimals", np.full(t.size, 10.0 ** -decimals)
    nonzero = t != 0.0
    exponent = np.floor(np.log10(np.abs(np.where(nonzero, t, 1.0))))
    for digits in range(1, MAX_DIGITS + 1):
        digit = np.where(nonzero, 10.0 ** (exponent + 1 - digits), 0.0)
        if _exact(np.where(nonzero, t / np.where(nonzero, digit, 1.0), 0.0)):
            yield f"{digits} significant digits", digit
            break
    if np.array_equal(t.astype(np.float32).astype(np.float64), t):  # stored as float32 (Parquet, MDF)
        yield "float32 precision", np.spacing(np.abs(t).astype(np.float32)).astype(np.float64)


def _start_interval(t: np.ndarray, digit: np.ndarray, step: float) -> tuple[float, float]:
    """The first stamps t0 for which every stamp i lies within half its last printed digit
    (plus float round-off) of t0 + i step: (lower, upper), empty if lower > upper."""
    half = 0.5 * digit + 8 * np.finfo(float).eps * np.abs(t)
    shifted = t - step * np.arange(t.size)
    return float(np.max(shifted - half)), float(np.min(shifted + half))


def _rate_within(t: np.ndarray, digit: np.ndarray) -> float | None:
    """The sample rate (Hz) of a uniform time base that rounds to the stamps ``t`` (each to its
    last printed digit), None if there is none: a whole number of Hz if one is consistent,
    else the middle of the consistent rates (two small linear programs over start and step)."""
    mean_rate = (t.size - 1) / (t[-1] - t[0])
    lo, hi = _start_interval(t, digit, 1.0 / round(mean_rate)) if round(mean_rate) > 0 else (1.0, 0.0)
    if lo <= hi:
        return float(round(mean_rate))
    from scipy.optimize import linprog  # only here: its import costs seconds on a busy machine

    half = 0.5 * digit + 8 * np.finfo(float).eps * np.abs(t)
    index = np.arange(t.size, dtype=np.float64) / (t.size - 1)
    scale = t[-1] - t[0]  # variables: start and duration, in units of the record's duration
    upper, lower = (t + half) / scale, (t - half) / scale
    # only the stamps on the convex hulls of the bounds can be binding: keeps the programs small
    keep = np.union1d(_hull(index, upper), _hull(index, lower))
    ones = np.ones(keep.size)
    a_ub = np.vstack([np.column_stack([ones, index[keep]]), -np.column_stack([ones, index[keep]])])
    b_ub = np.concatenate([upper[keep], -lower[keep]])
    steps = []
    for sign in (1.0, -1.0):
        res = linprog([0.0, sign], A_ub=a_ub, b_ub=b_ub, bounds=[(None, None), (0.5, 2.0)], method="highs")
        if res.status != 0:
            return None
        steps.append(res.x[1] * scale / (t.size - 1))
    return 2.0 / (steps[0] + steps[1])


def _hull(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Indices of the points (x, y) on their convex hull (x increasing, as sample indices are)."""
    from scipy.spatial import ConvexHull

    points = np.column_stack([x, (y - y[0]) - (y[-1] - y[0]) * x])  # detrended: a well-shaped hull
    try:
        return np.sort(ConvexHull(points).vertices)
    except Exception:  # qhull: all points on one line (a flat hull): any two of them bind
        return np.array([0, x.size - 1])


def regular_time(time_s: np.ndarray, *, file: object = None, where: str | None = None
                 ) -> tuple[np.ndarray, str | None]:
    """A strictly increasing time base (s) as uniform stamps, and a note if they were rounded.

    Returns ``time_s`` itself when its steps agree to round-off (:data:`EXACT`); the uniform
    stamps ``t0 + i / rate`` with a note when the stamps are a constant rate rounded to their
    printed precision; ``time_s`` itself when its steps still agree to :data:`DT_TOLERANCE`;
    raises :class:`DroptowerError` (naming ``file`` and ``where``) otherwise.
    """
    t = np.asarray(time_s, dtype=np.float64)
    n = t.size
    steps = np.diff(t)
    mean_step = (t[-1] - t[0]) / (n - 1)
    deviation = float(np.max(np.abs(steps - mean_step)))
    if deviation <= EXACT * mean_step + 8 * np.finfo(float).eps * float(np.max(np.abs(t))):
        return t, None
    for printed, digit in _precisions(t):
        rate = _rate_within(t, digit)
        if rate is not None:
            index = np.arange(n, dtype=np.float64)
            lo, hi = _start_interval(t, digit, 1.0 / rate)
            note = (f"time stamps printed to {printed} (steps {steps.min():.6g} .. {steps.max():.6g} s): "
                    f"taken as a constant {rate:.10g} Hz estimated from the whole record")
            return 0.5 * (lo + hi) + index / rate, note
    if deviation <= DT_TOLERANCE * mean_step:
        return t, None  # uniform enough: kept as they are
    precisions = printed_precision(t)
    shown = " or ".join(p for p, _ in precisions) or "any number of decimals"
    raise DroptowerError(f"the time step is not constant (median {float(np.median(steps)):.6g} s, range "
                         f"{steps.min():.6g} .. {steps.max():.6g} s), more than rounding to the stamps' printed "
                         f"precision ({shown}) explains; a constant sample rate is needed", file=file, where=where)
