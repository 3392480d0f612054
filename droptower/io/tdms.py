"""NI TDMS (``.tdms``) via npTDMS, an optional extra (``pip install droptower[formats]``).

Channel names are ``group/channel``; the unit is the ``unit_string`` property, the time base
the waveform properties ``wf_increment`` (s) and ``wf_start_offset`` when present.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from droptower.errors import DroptowerError, unreadable_file
from droptower.io.channels import Channel, Record


def read_tdms(path: str | Path) -> Record:
    """Read a TDMS file into a :class:`Record` (numeric channels only)."""
    path = Path(path)
    try:
        from nptdms import TdmsFile
    except ImportError:
        raise DroptowerError("reading TDMS files needs npTDMS: pip install 'droptower[formats]'", file=path) from None
    try:
        tdms = TdmsFile.read(path)
        channels: dict[str, Channel] = {}
        for group in tdms.groups():
            for ch in group.channels():
                data = ch[:]
                if data.dtype.kind not in "fiub":
                    continue
                props = dict(ch.properties)
                increment = props.get("wf_increment")
                name = f"{group.name}/{ch.name}"
                channels[name] = Channel(
                    name=name, unit=str(props.get("unit_string", "")), values=np.asarray(data, dtype=np.float64),
                    sample_rate_hz=1.0 / float(increment) if increment else None,
                    start_s=float(props.get("wf_start_offset", 0.0)),
                    metadata={k: v for k, v in props.items() if isinstance(v, (int, float, str))})
        metadata = {k: v for k, v in tdms.properties.items() if isinstance(v, (int, float, str))}
    except Exception as exc:  # npTDMS raises many kinds of errors for a bad file
        raise unreadable_file(path, exc, "TDMS file") from None
    if not channels:
        raise DroptowerError("TDMS file holds no numeric channels", file=path)
    return Record(path=path, channels=channels, metadata=metadata, format="TDMS")
