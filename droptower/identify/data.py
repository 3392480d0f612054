"""Identification data: imposed-angle / measured-torque histories in SI, constant time step.

A :class:`Segment` is what a model is fitted to: an angle history the model is driven
through from its virgin state, and the measured torque to compare with, NaN where it is not
compared (a lead-in, skipped transients, the parts of a record outside a block). Records come
from any file the readers take (:func:`segments_from_files`) or straight from arrays
(:func:`make_segment`).

A translational record (a mount, bushing or damper: displacement in m, force in N) is a
segment with ``units = "translational"`` whose ``angle_rad`` holds the displacement (m) and
``torque_nm`` the force (N): the models' equations do not change, only their reading (as in a
coupling file with ``units = "translational"``); reports name the fields for the record's
units (:mod:`droptower.io.fields`).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Iterable

import numpy as np

from droptower.errors import DroptowerError, finite_values
from droptower.identify.cycles import turning_points
from droptower.io.fields import UNITS
from droptower.io.timebase import regular_time

#: Duration of the half-cosine ramp from 0 rad to a record's first angle (s). The core starts
#: every history at 0 rad in its virgin state; a record that starts preloaded is reached
#: smoothly, and the ramp is never compared (the zero-dimensional model paper also leaves the preload application
#: out of the fit).
LEAD_IN_S = 1.0
#: Fewest samples a record may have.
MIN_SAMPLES = 32


@dataclass(frozen=True)
class Segment:
    """One history: ``angle_rad`` (N,) drives the model from 0 rad (virgin state), sampled
    every ``dt_s`` s; ``torque_nm`` (N,) is the measured torque, NaN where not compared.

    lead_in: number of leading samples that are the added ramp from 0 rad (not measured);
    metadata: the file's metadata; name: where it came from (file name, block label);
    units: ``"torsional"``, or ``"translational"`` (``angle_rad`` then holds the displacement
    in m, ``torque_nm`` the force in N).
    """

    name: str
    angle_rad: np.ndarray
    torque_nm: np.ndarray
    dt_s: float
    lead_in: int = 0
    metadata: dict[str, Any] = field(default_factory=dict)
    units: str = "torsional"

    @property
    def n(self) -> int:
        return self.angle_rad.size

    @property
    def compared(self) -> np.ndarray:
        """Boolean mask of the samples whose torque is compared."""
        return np.isfinite(self.torque_nm)

    @property
    def measured_angle(self) -> np.ndarray:
        """The record's angle without the lead-in (rad)."""
        return self.angle_rad[self.lead_in:]

    @property
    def measured_torque(self) -> np.ndarray:
        """The record's torque without the lead-in (N*m)."""
        return self.torque_nm[self.lead_in:]

    def window(self, start: int, stop: int, name: str | None = None) -> "Segment":
        """The history up to ``stop`` (record samples, lead-in excluded) with the torque
        compared only on ``[start, stop)``: a block of a longer record, keeping the model's
        load history before it."""
        a, b = self.lead_in + start, self.lead_in + stop
        torque = np.full(b, np.nan)
        torque[a:b] = self.torque_nm[a:b]
        return replace(self, name=name or f"{self.name}[{start}:{stop}]", angle_rad=self.angle_rad[:b],
                       torque_nm=torque)


def make_segment(time_s: np.ndarray, angle_rad: np.ndarray, torque_nm: np.ndarray, *, name: str = "",
                 metadata: dict[str, Any] | None = None, file: str | Path | None = None,
                 lead_in_s: float = LEAD_IN_S, skip_s: float = 0.0, units: str = "torsional") -> Segment:
    """Check one record and turn it into a :class:`Segment`.

    time_s, angle_rad, torque_nm: (N,) SI arrays (units ``"translational"``: displacement in
    m, force in N); the time step must be constant (time stamps rounded to their printed
    precision are, see :func:`droptower.io.timebase.regular_time`). The record
    must hold at least one load cycle (the angle reverses at least once by more than its
    noise). A record that does not start at 0 rad gets a half-cosine lead-in of ``lead_in_s``
    seconds from 0 rad; ``skip_s`` seconds at its start are not compared (transients).
    Raises :class:`DroptowerError` naming ``file`` on bad input.
    """
    names = ("time_s", "angle_rad", "torque_nm") if units != "translational" else ("time_s", "displacement_m", "force_n")
    t, x, y = (finite_values(v, n, file=file) for v, n in zip((time_s, angle_rad, torque_nm), names))
    if not (t.shape == x.shape == y.shape) or x.ndim != 1:
        raise DroptowerError(f"time, angle and torque differ in length ({t.size}, {x.size}, {y.size})", file=file)
    if x.size < MIN_SAMPLES:
        raise DroptowerError(f"record too short: {x.size} samples, at least {MIN_SAMPLES} needed", file=file)
    if units not in UNITS:
        raise DroptowerError(f"units must be one of {', '.join(UNITS)}, got {units!r}", file=file)
    steps = np.diff(t)
    if not (steps > 0).all():
        raise DroptowerError("the time is not strictly increasing", file=file)
    t, _ = regular_time(t, file=file)
    dt = float((t[-1] - t[0]) / (t.size - 1))
    if turning_points(x).size < 1:
        raise DroptowerError(f"record too short to hold one load cycle: the angle never reverses "
                             f"({x.size} samples, {x.size * dt:.3g} s)", file=file)
    y = y.copy()
    n_skip = int(round(skip_s / dt))
    y[:n_skip] = np.nan
    if not np.isfinite(y).any():
        raise DroptowerError("no torque samples left to compare", file=file)
    n_lead = 0
    if abs(x[0]) > 1e-6 * max(float(np.max(np.abs(x))), 1e-12):
        n_lead = max(int(round(lead_in_s / dt)), 2)
        ramp = x[0] * 0.5 * (1.0 - np.cos(np.pi * np.arange(1, n_lead + 1) / n_lead))
        x = np.concatenate([ramp[:-1], x])
        y = np.concatenate([np.full(n_lead - 1, np.nan), y])
        n_lead -= 1
    return Segment(name or (Path(file).name if file else "record"), x, y, dt, n_lead, dict(metadata or {}), units)


def segments_from_files(paths: Iterable[str | Path], roles: dict[str, str] | None = None, *,
                        skip_s: float = 0.0, notes: list[str] | None = None, sample_rate_hz: float | None = None,
                        sample_interval_s: float | None = None) -> list[Segment]:
    """Read servo records from files of any format the readers take: imposed angle and measured
    torque, or imposed displacement and measured force (a translational record).

    roles: channel role -> ``NAME[:UNIT]`` (roles ``time``, ``angle``,
    ``torque``, ``displacement``, ``force``); missing roles are found by name and units
    converted to SI (see :func:`droptower.io.mapping.map_servo_channels`). Every record must be
    of the same kind. notes: gets ``"<file>: <note>"`` for what was assumed in reading a file
    (rounded time stamps taken as a constant rate). sample_rate_hz (Hz) or sample_interval_s
    (s): the time base of records without a time channel, as published large-strain tests
    often are (the time is then ``arange(n) * sample_interval_s``); the records are read as
    :func:`droptower.servo.records.read_servo_signals` reads them for the bench's evaluation.
    """
    from droptower.servo.records import read_servo_signals, time_base_rate

    rate = time_base_rate(sample_rate_hz, sample_interval_s)
    out = []
    for path in paths:
        signals = read_servo_signals(path, roles, rate)
        if out and signals.units != out[0].units:
            raise DroptowerError(f"a {signals.units} record among {out[0].units} ones ({out[0].name}): "
                                 "identify from records of one kind", file=path)
        if notes is not None:
            notes.extend(f"{path}: {text}" for text in signals.notes)
        out.append(make_segment(signals.time_s, signals.motion_si, signals.load_si, name=Path(path).name,
                                metadata=signals.metadata, file=path, skip_s=skip_s, units=signals.units))
    return out


def common_units(segments: list[Segment], what: str = "records") -> str:
    """The units shared by all ``segments`` (a mix is a one-line error)."""
    kinds = sorted({s.units for s in segments})
    if len(kinds) > 1:
        raise DroptowerError(f"the {what} mix torsional and translational records "
                             f"({', '.join(s.name for s in segments if s.units == kinds[1])} translational)")
    return kinds[0] if kinds else "torsional"


@dataclass(frozen=True)
class DataScale:
    """Typical magnitudes of a data set, to scale bounds and initial guesses of any family.

    angle_rad: largest |angle|; amplitude_rad: largest half swing of a record;
    torque_nm: largest |torque|; stiffness_nm_per_rad: rms torque / rms angle (a secant
    stiffness); rate_rad_per_s: largest |d angle / dt|; frequency_hz: median characteristic
    frequency (rms rate / (2 pi rms angle swing)); units: the records' (for a translational
    record read m for rad and N for N*m).
    """

    angle_rad: float
    amplitude_rad: float
    torque_nm: float
    stiffness_nm_per_rad: float
    rate_rad_per_s: float
    frequency_hz: float
    units: str = "torsional"

    @classmethod
    def of(cls, segments: list[Segment]) -> "DataScale":
        x = np.concatenate([s.measured_angle for s in segments])
        y = np.concatenate([s.measured_torque for s in segments])
        ok = np.isfinite(y)
        rates = [np.abs(np.diff(s.angle_rad)) / s.dt_s for s in segments]
        freqs = [characteristic_frequency(s) for s in segments]
        amp = max(0.5 * float(np.ptp(s.measured_angle)) for s in segments)
        stiff = float(np.sqrt(np.mean(y[ok] ** 2) / max(np.mean(x[ok] ** 2), 1e-300)))
        return cls(float(np.max(np.abs(x))), amp, float(np.max(np.abs(y[ok]))), stiff,
                   float(max(r.max() for r in rates)), float(np.median(freqs)), common_units(segments))


def characteristic_frequency(segment: Segment) -> float:
    """rms(d angle/dt) / (2 pi rms(angle - mean)) (Hz): the frequency of a sine, a weighted
    mean frequency of any other history."""
    x = segment.measured_angle
    v = np.diff(x) / segment.dt_s
    swing = np.sqrt(np.mean((x - x.mean()) ** 2))
    return float(np.sqrt(np.mean(v ** 2)) / (2.0 * np.pi * max(swing, 1e-300)))
