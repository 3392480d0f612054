"""Test helpers: continuous recordings made of single-drop rig logs, and writers for the lab
formats the readers take (catman .BIN, MDF4, TDMS, MTS 793 .dat).

A recording is the drops' logs one after the other with a pause before each: the pause rests
at the level the last log ended at, moves in its middle fifth to the level the next log starts
at (a new preload) plus a drift (a sensor zero that wanders: every channel's level moves by a
random step from one drop to the next), and has its own noise. The logs' samples are kept as
they are except for that level, so each drop's pre-trigger baseline removes it and the results
must equal the single logs'.
"""
from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

#: the drift step (standard deviation between two drops) and the pause's noise per column
DRIFT = {"angle_rad": 2e-4, "laser_distance_m": 3e-5, "torque_nm": 15.0, "impact_force_n": 3.0}
PAUSE_NOISE = {"angle_rad": 6e-6, "laser_distance_m": 1e-6, "torque_nm": 2.0, "impact_force_n": 5.0}


def concatenate(logs: list[tuple[np.ndarray, dict[str, np.ndarray]]], pauses_s: list[float], seed: int = 0
                ) -> tuple[np.ndarray, dict[str, np.ndarray], list[int]]:
    """(time_s, columns, first sample of each log) of the recording: ``pauses_s[i]`` before log i.

    logs: (time_s, columns) of each single-drop log, one sample rate."""
    rng = np.random.default_rng(seed)
    dt = float(np.diff(logs[0][0]).mean())
    names = list(logs[0][1])
    parts: dict[str, list[np.ndarray]] = {n: [] for n in names}
    level = dict.fromkeys(names, 0.0)
    starts, n = [], 0
    for (_, columns), pause in zip(logs, pauses_s):
        m = int(round(pause / dt))
        for name in names:
            x = columns[name]
            new = level[name] + rng.normal(0.0, DRIFT.get(name, 0.0))
            end = float(np.mean(parts[name][-1][-20:])) if parts[name] else float(np.mean(x[:20])) + new
            # the pause joins the logs: the lever rests, the operator sets the next drop (a preload,
            # a wandering zero) in the middle fifth of the pause, the lever rests again
            ramp = np.interp(np.arange(m), [0.0, 0.4 * m, 0.6 * m, m], [end, end, *[float(np.mean(x[:20])) + new] * 2])
            parts[name] += [ramp + rng.normal(0.0, PAUSE_NOISE.get(name, 0.0), m), x + new]
            level[name] = new
        starts.append(n + m)
        n += m + columns[names[0]].size
    return np.arange(n) * dt, {k: np.concatenate(v) for k, v in parts.items()}, starts


def write_catman(path: Path, sample_rate_hz: float, columns: dict[str, np.ndarray], units: dict[str, str]) -> Path:
    """A catman .BIN (file ID 5012, 8-byte values) as :mod:`droptower.io.catman` documents it."""

    def string(text: str) -> bytes:
        raw = text.encode("cp1252")
        return struct.pack("<h", len(raw)) + raw

    names = list(columns)
    n = columns[names[0]].size
    head = struct.pack("<h", 5012)
    after_offset = string("recording") + string("0") + string("") * 31
    headers = []
    for name in names:
        ext = bytearray(148)
        struct.pack_into("<dd", ext, 0, 0.0, 1000.0 / sample_rate_hz)
        ext[140] = 0  # ExportFormat: float64
        headers.append(struct.pack("<hi", 1, n) + string(name) + string(units.get(name, "")) + string("")
                       + struct.pack("<hhdi", 0, 8, 0.0, len(ext)) + bytes(ext))
    table_size = 2 + 4 + 4 * len(names) + 4
    first = len(head) + 4 + len(after_offset) + table_size
    offsets, pos = [], first
    for h in headers:
        offsets.append(pos + 2)  # the offset of the channel's length entry, after its location
        pos += len(h)
    table = struct.pack("<hi", len(names), n) + struct.pack(f"<{len(names)}i", *offsets) + struct.pack("<i", 1)
    data = b"".join(np.asarray(columns[k], dtype="<f8").tobytes() for k in names)
    path.write_bytes(head + struct.pack("<i", pos) + after_offset + table + b"".join(headers) + data)
    return path


def write_mdf(path: Path, time_s: np.ndarray, columns: dict[str, np.ndarray], units: dict[str, str]) -> Path:
    from asammdf import MDF, Signal

    with MDF(version="4.10") as mdf:
        mdf.append([Signal(columns[k], time_s, name=k, unit=units.get(k, "")) for k in columns])
        mdf.save(path, overwrite=True)
    return path


def write_tdms(path: Path, sample_rate_hz: float, columns: dict[str, np.ndarray], units: dict[str, str]) -> Path:
    import nptdms

    with nptdms.TdmsWriter(path) as writer:
        writer.write_segment([nptdms.ChannelObject("drops", k, np.asarray(v, dtype=np.float64), properties={
            "unit_string": units.get(k, ""), "wf_increment": 1.0 / sample_rate_hz, "wf_start_offset": 0.0})
            for k, v in columns.items()])
    return path


def write_mts_dat(path: Path, time_s: np.ndarray, columns: dict[str, np.ndarray], units: dict[str, str]) -> Path:
    """An MTS 793 tab-separated export (one data buffer)."""
    names = ["Running Time", *columns]
    lines = ["MTS793|MPT|ENU|1|2|.|/|:|1|0|0|A", "", f"Data Acquisition\t\tTime:\t{float(time_s[-1])!r}\tSec",
             "\t".join(names), "\t".join(["Sec", *(units.get(k, "") for k in columns)])]
    table = np.column_stack([time_s, *columns.values()])
    lines += ["\t".join(repr(float(v)) for v in row) for row in table]
    path.write_text("\n".join(lines) + "\n")
    return path
