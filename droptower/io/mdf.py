"""MDF4 (ASAM MDF, ``.mf4``/``.mdf``) via asammdf, an optional extra (``pip install droptower[formats]``).

Each channel keeps its unit and the time stamps of its channel group (its master channel).
"""
from __future__ import annotations

import functools
import gc
import re
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from droptower.errors import DroptowerError, unreadable_file
from droptower.io.channels import Channel, Record


def read_mdf(path: str | Path) -> Record:
    """Read an MDF file into a :class:`Record`; each channel gets its group's time base (s)."""
    path = Path(path)
    try:
        from asammdf import MDF
    except ImportError:
        raise DroptowerError("reading MDF files needs asammdf: pip install 'droptower[formats]'", file=path) from None
    channels: dict[str, Channel] = {}
    problem = None
    hook = sys.unraisablehook
    sys.unraisablehook = functools.partial(_quiet_asammdf_cleanup, hook)
    # asammdf copies an unfinalised file into its temporary folder and, if the copy then fails
    # to parse, leaves it there: give it a folder of our own, removed whatever happens
    scratch = tempfile.TemporaryDirectory(prefix="droptower_mdf_", ignore_cleanup_errors=True)
    try:
        problem, metadata = _read(MDF, path, channels, scratch.name)
        if problem is not None:  # a full collection costs ~0.1 s in a large process: not per good file
            gc.collect()  # a reader that failed half-built is freed here: its __del__ fails inside asammdf
    finally:
        sys.unraisablehook = hook
        scratch.cleanup()
    if problem is not None:
        raise unreadable_file(path, problem, "MDF file")
    if not channels:
        raise DroptowerError("MDF file holds no numeric channels", file=path)
    return Record(path=path, channels=channels, metadata=metadata, format="MDF")


def _quiet_asammdf_cleanup(hook: Any, unraisable: Any) -> None:
    """Drop the error asammdf's ``__del__`` raises for a file it failed to open; pass on the rest."""
    if str(getattr(unraisable.object, "__module__", "")).startswith("asammdf"):  # the failing MDF4.__del__
        return
    hook(unraisable)


def _read(MDF: Any, path: Path, channels: dict[str, Channel], scratch: str) -> tuple[str | None, dict[str, str]]:
    """Fill ``channels`` from the file (asammdf's temporary files in ``scratch``); returns (the
    problem in words or None, metadata)."""
    try:
        with MDF(path, temporary_folder=scratch) as mdf:
            for signal in mdf.iter_channels():
                if signal.samples.dtype.kind not in "fiub":
                    continue  # text, byte arrays, structures: not a measured quantity
                name = signal.name if signal.name not in channels else f"{signal.name} (group {signal.group_index})"
                channels[name] = Channel(
                    name=name, unit=signal.unit or "", values=np.asarray(signal.samples, dtype=np.float64),
                    time_s=np.asarray(signal.timestamps, dtype=np.float64),
                    metadata={"group": signal.group_index, "comment": signal.comment or ""})
            return None, {"version": str(mdf.version), "start_time": str(mdf.start_time)}
    except Exception as exc:  # asammdf raises many kinds of errors for a bad file
        # it names the file by its memory map: "'<mmap.mmap closed=False, ...>' is not a valid MDF file"
        return re.sub(r"'?<mmap\.mmap[^>]*>'?", "the file", " ".join(str(exc).split())), {}
