"""Identification data: imposed-angle / measured-torque histories in SI, constant time step.

A :class:`Segment` is what a model is fitted to: an angle history the model is driven
through from its virgin state, and the measured torque to compare with, NaN where it is not
compared (a lead-in, skipped transients, the parts of a record outside a block). Records come
from any file the readers take (:func:`segments_from_files`) or straight from arrays
(:func:`make_segment`).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Iterable

import numpy as np

from droptower.errors import DroptowerError
from droptower.identify.cycles import turning_points

#: Duration of the half-cosine ramp from 0 rad to a record's first angle (s). The core starts
#: every history at 0 rad in its virgin state; a record that starts preloaded is reached
#: smoothly, and the ramp is never compared (seed 000 also leaves the preload application
#: out of the fit).
LEAD_IN_S = 1.0
#: Fewest samples a record may have.
MIN_SAMPLES = 32
#: Largest deviation of one time step from the median step (relative) still taken as uniform.
DT_TOLERANCE = 1e-3


@dataclass(frozen=True)
class Segment:
    """One history: ``angle_rad`` (N,) drives the model from 0 rad (virgin state), sampled
    every ``dt_s`` s; ``torque_nm`` (N,) is the measured torque, NaN where not compared.

    lead_in: number of leading samples that are the added ramp from 0 rad (not measured);
    metadata: the file's metadata; name: where it came from (file name, block label).
    """

    name: str
    angle_rad: np.ndarray
    torque_nm: np.ndarray
    dt_s: float
    lead_in: int = 0
    metadata: dict[str, Any] = field(default_factory=dict)

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
                 lead_in_s: float = LEAD_IN_S, skip_s: float = 0.0) -> Segment:
    """Check one record and turn it into a :class:`Segment`.

    time_s, angle_rad, torque_nm: (N,) SI arrays; the time step must be constant. The record
    must hold at least one load cycle (the angle reverses at least once by more than its
    noise). A record that does not start at 0 rad gets a half-cosine lead-in of ``lead_in_s``
    seconds from 0 rad; ``skip_s`` seconds at its start are not compared (transients).
    Raises :class:`DroptowerError` naming ``file`` on bad input.
    """
    t = np.asarray(time_s, dtype=float)
    x = np.asarray(angle_rad, dtype=float)
    y = np.asarray(torque_nm, dtype=float)
    if not (t.shape == x.shape == y.shape) or x.ndim != 1:
        raise DroptowerError(f"time, angle and torque differ in length ({t.size}, {x.size}, {y.size})", file=file)
    if x.size < MIN_SAMPLES:
        raise DroptowerError(f"record too short: {x.size} samples, at least {MIN_SAMPLES} needed", file=file)
    if not (np.isfinite(x).all() and np.isfinite(t).all()):
        raise DroptowerError("the angle or the time holds NaN values", file=file)
    steps = np.diff(t)
    dt = float(np.median(steps))
    if not dt > 0 or np.max(np.abs(steps - dt)) > DT_TOLERANCE * dt:
        raise DroptowerError(f"the time step is not constant (median {dt:.6g} s, range {steps.min():.6g} .. "
                             f"{steps.max():.6g} s); identification needs a constant sample rate", file=file)
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
    return Segment(name or (Path(file).name if file else "record"), x, y, dt, n_lead, dict(metadata or {}))


def segments_from_files(paths: Iterable[str | Path], roles: dict[str, str] | None = None, *,
                        skip_s: float = 0.0) -> list[Segment]:
    """Read imposed-angle / measured-torque records from files of any format the readers take.

    roles: channel roles as from ``--channel ROLE=NAME[:UNIT]`` (``time``, ``angle``,
    ``torque``); missing roles are found by name (see :mod:`droptower.io.mapping`).
    """
    from droptower.io import read_any
    from droptower.io.mapping import map_channels

    out = []
    for path in paths:
        record = read_any(path)
        signals = map_channels(record, roles, sensor_radius_m=None, radius_flags="--channel angle=NAME[:UNIT]",
                               sample_rate_flag=None)
        if signals.torque_nm is None:
            raise DroptowerError("no torque channel found; name it with --channel torque=NAME[:UNIT] "
                                 f"(the file has: {', '.join(repr(n) for n in record.channels)})", file=path)
        out.append(make_segment(signals.time_s, signals.angle_rad, signals.torque_nm, name=Path(path).name,
                                metadata=signals.metadata, file=path, skip_s=skip_s))
    return out


@dataclass(frozen=True)
class DataScale:
    """Typical magnitudes of a data set, to scale bounds and initial guesses of any family.

    angle_rad: largest |angle|; amplitude_rad: largest half swing of a record;
    torque_nm: largest |torque|; stiffness_nm_per_rad: rms torque / rms angle (a secant
    stiffness); rate_rad_per_s: largest |d angle / dt|; frequency_hz: median characteristic
    frequency (rms rate / (2 pi rms angle swing)).
    """

    angle_rad: float
    amplitude_rad: float
    torque_nm: float
    stiffness_nm_per_rad: float
    rate_rad_per_s: float
    frequency_hz: float

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
                   float(max(r.max() for r in rates)), float(np.median(freqs)))


def characteristic_frequency(segment: Segment) -> float:
    """rms(d angle/dt) / (2 pi rms(angle - mean)) (Hz): the frequency of a sine, a weighted
    mean frequency of any other history."""
    x = segment.measured_angle
    v = np.diff(x) / segment.dt_s
    swing = np.sqrt(np.mean((x - x.mean()) ** 2))
    return float(np.sqrt(np.mean(v ** 2)) / (2.0 * np.pi * max(swing, 1e-300)))
