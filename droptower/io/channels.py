"""The one channel model every reader returns, real logs and virtual ones alike.

A :class:`Record` is what a file holds: named channels with their units as written in the
file, their own time base, and the file's metadata. Readers never convert units or guess
roles; the mapping of channels to roles (time, angle, torque, ...) and the conversion to SI
happen afterwards, in one place (:mod:`droptower.io.mapping`).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np


@dataclass(frozen=True)
class Channel:
    """One measured quantity.

    Attributes
    ----------
    name: channel name as written in the file.
    unit: unit as written in the file (``"N*m"``, ``"deg"``, ``"mm"``, ``""`` if none).
    values: float64 samples; invalid samples (catman's -1e6 marker) are kept as NaN and
        counted in ``invalid``, never silently treated as data.
    time_s: the channel's own time base in seconds, or None if it is given by
        ``sample_rate_hz`` (uniform, starting at ``start_s``).
    sample_rate_hz: sampling rate in Hz if uniform and known.
    invalid: boolean mask of samples the file marks as invalid (or None if none).
    metadata: anything else the file says about the channel.
    """

    name: str
    unit: str
    values: np.ndarray
    time_s: np.ndarray | None = None
    sample_rate_hz: float | None = None
    start_s: float = 0.0
    invalid: np.ndarray | None = None
    metadata: dict[str, Any] = field(default_factory=dict)

    def time(self) -> np.ndarray | None:
        """The channel's time base in s: its own, or built from the sample rate."""
        if self.time_s is not None:
            return self.time_s
        if self.sample_rate_hz:
            return self.start_s + np.arange(self.values.size) / self.sample_rate_hz
        return None


@dataclass
class Record:
    """The contents of one log file: ordered channels plus file-level metadata."""

    path: Path
    channels: dict[str, Channel]
    metadata: dict[str, Any] = field(default_factory=dict)
    format: str = ""

    def __getitem__(self, name: str) -> Channel:
        return self.channels[name]

    def names(self) -> list[str]:
        return list(self.channels)
