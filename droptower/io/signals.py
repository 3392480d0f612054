"""A drop test's signals in SI, after channel mapping: what the extractor consumes.

Readers return a :class:`~droptower.io.channels.Record` (channels as the file has them);
:func:`droptower.io.mapping.map_channels` picks the roles and converts units into a
:class:`DropSignals`. The extractor never sees file formats or units.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np


@dataclass
class DropSignals:
    """One test, SI units, one common time base.

    time_s: (N,) strictly increasing; angle_rad: (N,) torsion angle (from the angle channel,
    or from the laser distance divided by the sensor radius); torque_nm: (N,) flange torque or
    None; impact_force_n: (N,) impact force or None; metadata: the file's test metadata
    (e.g. inertia_kgm2, drop_mass_kg, drop_height_m, preload_nm, repeat, seed);
    source: the file the signals came from; notes: what was assumed in reading it (e.g.
    rounded time stamps taken as a constant rate).
    """

    time_s: np.ndarray
    angle_rad: np.ndarray
    torque_nm: np.ndarray | None = None
    impact_force_n: np.ndarray | None = None
    metadata: dict[str, Any] = field(default_factory=dict)
    source: Path | None = None
    notes: list[str] = field(default_factory=list)

    @property
    def sample_rate_hz(self) -> float:
        """Mean sample rate (Hz)."""
        return (self.time_s.size - 1) / (self.time_s[-1] - self.time_s[0])


@dataclass
class ServoSignals:
    """One servo-hydraulic record in SI on one time base: the imposed motion and the measured load.

    units: ``"torsional"`` (motion_si: angle in rad, load_si: torque in N*m) or
    ``"translational"`` (displacement in m, force in N); time_s: (N,) strictly increasing and
    uniform; metadata: the file's metadata; source: the file; notes: what was assumed in
    reading it (e.g. rounded time stamps taken as a constant rate).
    """

    time_s: np.ndarray
    motion_si: np.ndarray
    load_si: np.ndarray | None
    units: str = "torsional"
    metadata: dict[str, Any] = field(default_factory=dict)
    source: Path | None = None
    notes: list[str] = field(default_factory=list)
