"""Every drop in a continuous recording: where each one starts and which samples are its own.

A lab often records a series of drops in one file (five repeats of one height, a morning's
drops). Each drop is an impact after a quiet stretch: on the force channel a pulse (Rapp et al. 2022:
~0.3 ms) standing out of the force's running median; without one the angular velocity jumping
out of its band after rest (to three times the band within 2 ms: a preload being set moves
slower). Pulses less than ``min_spacing_s`` after a drop's first impact are that drop's later
contacts (its double-impact check sees them), not new drops.

Each drop gets its own span of samples: from ``pre_trigger_s`` before its impact (its own
pre-trigger baseline, so offsets, drift and preload between drops cancel) to where its
oscillation has died out (the angular velocity stays within the impact detection's band for
half a period) and as long again at rest, at the latest the start of the next drop's
pre-trigger: what the operator does in the pause (a new preload, a wandering zero) is not part
of the drop. A record with one drop keeps the whole record as its span, as a single-drop log
always has. The per-drop evaluation (:func:`droptower.extract.extract` on the span) is the
single-drop one: its baseline, fit window and double-impact check.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from droptower.errors import DroptowerError
from droptower.extract.impact_detection import IMPACT_SNR, NOISE_FACTOR, PEAK_FRACTION, MIN_PRETRIGGER
from droptower.io.signals import DropSignals

PRE_TRIGGER_S = 0.005        # pre-trigger per drop in a continuous recording (the rig's default)
MIN_DROP_SPACING_S = 0.5     # a pulse sooner after a drop's impact is one of its later contacts
FORCE_MEDIAN_S = 0.005       # running median of the force: the pulse (~0.3 ms) stands out of it
VELOCITY_S = 1e-3            # the angular velocity is fitted over this long ...
RISE_S = 2e-3                # ... so an impact's jump in it takes about as long (the contact: ~0.3 ms)
JUMP_RATIO = 3.0             # the jump reaches this many times the band within RISE_S


@dataclass(frozen=True)
class DropSpan:
    """One drop of a record (sample indices into the record's time base).

    index: 1-based number of the drop in the record; start, stop: its samples ``[start, stop)``
    (its pre-trigger starts at ``start``); onset: the first sample of its impact as located in
    the whole record; next_onset: the next drop's, or None for the last drop; cut: the next
    drop's pre-trigger began before this drop's oscillation had died out.
    """

    index: int
    start: int
    stop: int
    onset: int
    next_onset: int | None
    cut: bool = False


def _robust_std(x: np.ndarray) -> float:
    return 1.4826 * float(np.median(np.abs(x - np.median(x))))


def _onsets(above: np.ndarray) -> np.ndarray:
    """Samples where ``above`` turns true after a false sample."""
    return np.flatnonzero(above[1:] & ~above[:-1]) + 1


def _force_onsets(force: np.ndarray, fs: float) -> np.ndarray:
    """Pulses of the force over its running median (of ``FORCE_MEDIAN_S`` blocks), beyond
    max(6 σ, 5 % of the largest)."""
    width = max(3, int(round(FORCE_MEDIAN_S * fs)))
    blocks = force[: force.size // width * width].reshape(-1, width)
    if blocks.shape[0] >= 2:  # the medians of consecutive blocks, joined: the pulse moves none of them
        centres = (np.arange(blocks.shape[0]) + 0.5) * width
        excess = force - np.interp(np.arange(force.size), centres, np.median(blocks, axis=1))
    else:
        excess = force - np.median(force)
    sign = 1.0 if excess.max() >= -excess.min() else -1.0
    excess = sign * excess
    noise, height = _robust_std(excess), float(excess.max())
    if height <= IMPACT_SNR * noise or height == 0.0:
        raise DroptowerError(f"no impact found on channel 'impact_force': its largest pulse ({height:.3g}) is within "
                             f"{IMPACT_SNR:g}x the noise ({noise:.3g})")
    return _onsets(excess > max(NOISE_FACTOR * noise, PEAK_FRACTION * height))


def _angular_velocity(angle: np.ndarray, fs: float) -> tuple[np.ndarray, float]:
    """dφ/dt (rad/s) from a local quadratic fit over ``VELOCITY_S`` (Savitzky–Golay: the
    impact's jump stands out of the sensor noise, which the plain difference would amplify),
    and the standard deviation of its noise: the angle's white noise, estimated from its second
    difference (std √6 σ; an oscillation's is orders of magnitude smaller at these sample
    rates), through the filter."""
    from scipy.signal import savgol_coeffs, savgol_filter  # here: scipy.signal takes ~0.7 s to import

    width = min(max(5, int(round(VELOCITY_S * fs)) | 1), (angle.size - 1) | 1 if angle.size % 2 == 0 else angle.size)
    if width < 5:
        raise DroptowerError(f"the record has only {angle.size} samples")
    noise = _robust_std(np.diff(angle, 2)) / np.sqrt(6.0)
    gain = float(np.linalg.norm(savgol_coeffs(width, 2, deriv=1))) * fs
    return savgol_filter(angle, width, 2, deriv=1) * fs, noise * gain


def _velocity_onsets(velocity: np.ndarray, noise: float, pre: int, rise: int) -> np.ndarray:
    """Where |dφ/dt| leaves its band after ``pre`` samples in it (a drop starts from rest) and
    reaches ``JUMP_RATIO`` times the band within ``rise`` samples: the impact sets the lever
    moving within its contact, while a preload being set or a decaying ringing crossing the
    band do not jump."""
    speed = np.abs(velocity)
    height = float(speed.max())
    if height <= IMPACT_SNR * noise or height == 0.0:
        raise DroptowerError(f"no impact found on channel 'angle': its largest rate ({height:.3g} rad/s) is within "
                             f"{IMPACT_SNR:g}x the noise ({noise:.3g} rad/s)")
    band = max(NOISE_FACTOR * noise, PEAK_FRACTION * height)
    above = speed > band
    import pandas as pd  # here: importing the extractor loads no pandas

    recent = pd.Series(above.astype(float)).rolling(pre, min_periods=1).max().shift(1, fill_value=1.0).to_numpy()
    starts = np.flatnonzero(above & (recent == 0.0))
    return np.array([i for i in starts if speed[i:i + rise].max() >= JUMP_RATIO * band], dtype=int)


def _settled(velocity: np.ndarray, noise: float, onset: int, stop: int) -> int | None:
    """The end of the first stretch of half a period after the impact in which dφ/dt, less its
    running median over a period (a slow drift or a preload being set in the pause), stays
    within max(6 σ, 5 % of the drop's peak rate): the drop's oscillation has died out. None if
    it does not before ``stop``. Half a period is twice the time from the impact to the first
    swing's turning point (where dφ/dt first returns to zero)."""
    part = velocity[onset:stop]
    if part.size < 4:
        return None
    first = int(np.argmax(np.abs(part)))
    turning = np.flatnonzero(np.sign(part[first]) * part[first:] <= 0.0)
    if not turning.size:
        return None
    need = max(2 * (first + int(turning[0])), 4)
    import pandas as pd

    trend = pd.Series(part).rolling(2 * need, center=True, min_periods=1).median().to_numpy()
    quiet = np.abs(part - trend) <= max(NOISE_FACTOR * noise, PEAK_FRACTION * abs(float(part[first])))
    runs = np.convolve(quiet, np.ones(need, dtype=int), mode="valid")  # quiet samples in each stretch
    full = np.flatnonzero(runs[first:] == need)
    return None if not full.size else onset + first + int(full[0]) + need


def find_drops(signals: DropSignals, *, pre_trigger_s: float = PRE_TRIGGER_S,
               min_spacing_s: float = MIN_DROP_SPACING_S) -> list[DropSpan]:
    """The drops of a record, in time order (see the module docstring).

    pre_trigger_s: the pre-trigger of each drop of a record with several (s); min_spacing_s:
    the shortest time between two drops' impacts (s). Raises :class:`DroptowerError` when the
    record holds no impact.
    """
    time = np.asarray(signals.time_s)
    fs = signals.sample_rate_hz
    pre = max(int(round(pre_trigger_s * fs)), MIN_PRETRIGGER + 2)
    velocity = noise = None
    if signals.impact_force_n is not None:
        candidates = _force_onsets(np.asarray(signals.impact_force_n, dtype=float), fs)
    else:
        velocity, noise = _angular_velocity(np.asarray(signals.angle_rad, dtype=float), fs)
        candidates = _velocity_onsets(velocity, noise, pre, max(int(round(RISE_S * fs)), 2))
    onsets: list[int] = []
    for i in candidates:
        if not onsets or time[i] - time[onsets[-1]] >= min_spacing_s:
            onsets.append(int(i))
    if not onsets:
        raise DroptowerError("no impact found in the record")
    if len(onsets) == 1:
        return [DropSpan(1, 0, time.size, onsets[0], None, False)]
    if velocity is None:
        velocity, noise = _angular_velocity(np.asarray(signals.angle_rad, dtype=float), fs)
    starts = [max(0, o - pre) for o in onsets]
    spans = []
    for k, (start, onset) in enumerate(zip(starts, onsets)):
        limit = starts[k + 1] if k + 1 < len(onsets) else time.size
        settled = _settled(velocity, noise, onset, limit)
        cut = settled is None and k + 1 < len(onsets)
        # at rest as long again after the oscillation: the span is mostly rest, as a single-drop log
        stop = limit if settled is None else min(limit, onset + 2 * (settled - onset))
        spans.append(DropSpan(k + 1, start, stop, onset,
                              onsets[k + 1] if k + 1 < len(onsets) else None, cut))
    return spans


def drop_signals(signals: DropSignals, span: DropSpan, conditions: dict[str, float] | None = None) -> DropSignals:
    """The samples of one drop, with its conditions (``drop_height_m``, ``drop_mass_kg``,
    ``inertia_kgm2``, ``preload_nm``) over the record's metadata."""
    part = slice(span.start, span.stop)

    def cut(x: np.ndarray | None) -> np.ndarray | None:
        return None if x is None else np.asarray(x)[part]

    return replace(signals, time_s=cut(signals.time_s), angle_rad=cut(signals.angle_rad),
                   torque_nm=cut(signals.torque_nm), impact_force_n=cut(signals.impact_force_n),
                   metadata={**signals.metadata, **(conditions or {})})


_RANGE = re.compile(r"^\s*(\d+)\s*(?:-\s*(\d+)\s*)?$")


def parse_drop_selection(text: str) -> set[int]:
    """``1,3-5`` -> {1, 3, 4, 5} (1-based drop numbers); anything else is a DroptowerError."""
    chosen: set[int] = set()
    for part in str(text).split(","):
        match = _RANGE.match(part)
        if not match:
            raise DroptowerError(f"`drops={text!r}`: expected drop numbers and ranges such as 1,3-5")
        first, last = int(match.group(1)), int(match.group(2) or match.group(1))
        if first < 1 or last < first:
            raise DroptowerError(f"`drops={text!r}`: drops are numbered from 1, ranges go upwards ({part.strip()})")
        chosen.update(range(first, last + 1))
    return chosen


#: the conditions a drop-conditions CSV may give, by column name (SI, units in the names)
CONDITION_COLUMNS = ("drop_height_m", "drop_mass_kg", "inertia_kgm2", "preload_nm")


def read_drop_conditions(path: str | Path) -> dict[int, dict[str, float]]:
    """A drop-conditions table ``drop_index,drop_height_m,drop_mass_kg,inertia_kgm2,preload_nm``
    (any of the condition columns; CSV in any dialect, ``.xlsx``, ``.parquet`` or ``.json``, read
    by its suffix; units in the names converted) -> {drop number: {column: value}}; empty
    cells are left out. It is keyed by the drop's number in a recording of several drops; a
    table keyed by file is a per-file conditions table (:func:`droptower.io.read_conditions`)."""
    from droptower.io.conditions import CONDITION_NAMES, _normalise
    from droptower.io.table_reader import read_table

    path = Path(path)
    wanted = {"drop_index": ("drop", "drop number", "drop no"), **{c: CONDITION_NAMES[c] for c in CONDITION_COLUMNS}}
    table = read_table(path, wanted, what="drop conditions")
    if "drop_index" not in table.columns:

        if any(_normalise(c) in ("file", *CONDITION_NAMES["file"]) for c in table.columns):
            raise DroptowerError("the drop conditions are keyed by drop_index (the drop's number in a recording); "
                                 "this table names files: it is a per-file conditions table, give it as `conditions`",
                                 file=path)
        raise DroptowerError("the drop conditions need a 'drop_index' column", file=path)
    unknown = [c for c in table.columns if c not in wanted]
    if unknown:
        raise DroptowerError(f"unknown column(s) {', '.join(map(repr, unknown))}; expected drop_index and any of "
                             f"{', '.join(CONDITION_COLUMNS)}", file=path)
    from droptower.io.conditions import parse_number

    try:
        values = table.apply(lambda col: col.map(lambda v: np.nan if parse_number(v) is None else parse_number(v))).astype(float)
    except (ValueError, TypeError) as exc:
        raise DroptowerError(f"a value is not a number ({exc})", file=path) from None
    index = values["drop_index"]
    if not (index.notna().all() and (index == index.round()).all() and (index >= 1).all()) or index.duplicated().any():
        raise DroptowerError("drop_index must be distinct whole numbers from 1", file=path)
    return {int(row.drop_index): {k: float(v) for k, v in row._asdict().items() if k != "drop_index" and np.isfinite(v)}
            for row in values.itertuples(index=False)}
