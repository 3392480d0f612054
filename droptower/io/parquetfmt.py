"""Generic Parquet logs: every numeric column is a channel.

The unit comes from the column's field metadata (key ``unit``), else from brackets in the name
(``Torque [N*m]``), else from a unit suffix (``torque_nm``). Droptower logs (with their schema
metadata) are read by :func:`droptower.io.droptower_log.read_log` instead.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from droptower.errors import DroptowerError, unreadable_file
from droptower.io.channels import Channel, Record
from droptower.io.csvfmt import split_name_unit
from droptower.io.droptower_log import unit_from_name


def read_parquet(path: str | Path) -> Record:
    """Read a Parquet table into a :class:`Record` (numeric columns only)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    path = Path(path)
    try:
        table = pq.read_table(path, use_threads=False)  # see droptower_log.ARROW_THREADS
    except (OSError, pa.ArrowException) as exc:
        raise unreadable_file(path, exc, "Parquet file") from None
    channels: dict[str, Channel] = {}
    for field in table.schema:
        if not (pa.types.is_floating(field.type) or pa.types.is_integer(field.type)):
            continue
        unit = (field.metadata or {}).get(b"unit", b"").decode()
        name, bracket_unit = split_name_unit(field.name)
        channels[name] = Channel(
            name=name, unit=unit or bracket_unit or unit_from_name(field.name),
            values=table.column(field.name).to_numpy().astype(np.float64, copy=False))
    if not channels:
        raise DroptowerError("Parquet file holds no numeric columns", file=path)
    return Record(path=path, channels=channels, metadata={}, format="parquet")
