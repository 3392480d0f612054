"""MDF4 (ASAM MDF, ``.mf4``/``.mdf``) via asammdf, an optional extra (``pip install droptower[formats]``).

Each channel keeps its unit and the time stamps of its channel group (its master channel).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from droptower.errors import DroptowerError
from droptower.io.channels import Channel, Record


def read_mdf(path: str | Path) -> Record:
    """Read an MDF file into a :class:`Record`; each channel gets its group's time base (s)."""
    path = Path(path)
    try:
        from asammdf import MDF
    except ImportError:
        raise DroptowerError("reading MDF files needs asammdf: pip install 'droptower[formats]'", file=path) from None
    channels: dict[str, Channel] = {}
    try:
        with MDF(path) as mdf:
            for signal in mdf.iter_channels():
                if signal.samples.dtype.kind not in "fiub":
                    continue  # text, byte arrays, structures: not a measured quantity
                name = signal.name if signal.name not in channels else f"{signal.name} (group {signal.group_index})"
                channels[name] = Channel(
                    name=name, unit=signal.unit or "", values=np.asarray(signal.samples, dtype=np.float64),
                    time_s=np.asarray(signal.timestamps, dtype=np.float64),
                    metadata={"group": signal.group_index, "comment": signal.comment or ""})
            metadata = {"version": str(mdf.version), "start_time": str(mdf.start_time)}
    except DroptowerError:
        raise
    except Exception as exc:  # asammdf raises many kinds of errors for a bad file
        raise DroptowerError(f"cannot read MDF file: {exc}", file=path) from None
    if not channels:
        raise DroptowerError("MDF file holds no numeric channels", file=path)
    return Record(path=path, channels=channels, metadata=metadata, format="MDF")
