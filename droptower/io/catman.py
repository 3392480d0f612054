"""HBM catman binary export (``.BIN``) reader: native, vectorised, no HBM software needed.

Layout from HBM's published description (``catmanBinaryFormat.xls``), little-endian; "short"
is int16, "long" int32, strings are a short length followed by that many bytes:

- global section: file ID (5006..5012), data offset (long), file comment, post-data offset
  string, 31 reserve strings, number of channels (short), maximum channel length (long), one
  long per channel giving the offset of that channel's length entry, reduction factor (long);
- per channel: database location (short), number of samples (long), name, unit, comment,
  format (short: 0 numeric double, 4 numeric float, 1 string, 2 binary), data width (short),
  date (double), size of the extended header (long) and the extended header
  (``VB_DB_CHANHEADER``: T0 (double, OLE date), dt (double, ms), ..., ExportFormat), then
  linearisation data, formula and sensor info (skipped: we jump to the next channel through
  the offset table);
- data area at the data offset: the channels one after the other, each as float64
  (ExportFormat 0), float32 (1), or int16 (2) preceded by two float64 min and max, with
  ``value = raw / 32767 * (max - min) + min``.

ExportFormat sits at byte 140 of the 148-byte extended header: the sample files (catman 5.5,
file ID 5012) show the published field list is 3 bytes short before ``NominalRange`` (the
value 2500.0 of the sample files' potentiometer is at byte 132, not 129). The three sample
files hold 0, 1, 2 there for their 8-, 4- and 2-byte precision.

catman writes -1000000 for a sample with no valid value (e.g. a sensor not connected); such
samples become NaN and are flagged in ``Channel.invalid``.
"""
from __future__ import annotations

import struct
from datetime import datetime, timedelta
from pathlib import Path

import numpy as np

from droptower.errors import DroptowerError, unreadable_file
from droptower.io.channels import Channel, Record

FILE_IDS = range(5006, 5013)
INVALID_MARKER = -1_000_000.0
EXPORT_FORMAT_OFFSET = 140  # in the extended channel header, see module docstring
_DTYPES = {0: np.dtype("<f8"), 1: np.dtype("<f4"), 2: np.dtype("<i2")}


class _Cursor:
    """Sequential little-endian reads from a bytes buffer; running past the end is an error."""

    def __init__(self, data: bytes, pos: int = 0):
        self.data, self.pos = data, pos

    def unpack(self, fmt: str):
        size = struct.calcsize("<" + fmt)
        if self.pos + size > len(self.data):
            raise EOFError
        values = struct.unpack_from("<" + fmt, self.data, self.pos)
        self.pos += size
        return values if len(values) > 1 else values[0]

    def string(self) -> str:
        length = self.unpack("h")
        if length < 0 or self.pos + length > len(self.data):
            raise EOFError
        raw = self.data[self.pos:self.pos + length]
        self.pos += length
        return raw.split(b"\0", 1)[0].decode("cp1252", "replace").strip()

    def raw(self, length: int) -> bytes:
        if length < 0 or self.pos + length > len(self.data):
            raise EOFError
        self.pos += length
        return self.data[self.pos - length:self.pos]


def _ole_date(days: float) -> str | None:
    """An OLE automation date (days since 1899-12-30) as ISO text, None if zero or absurd."""
    if not 1.0 < days < 2_958_465.0:
        return None
    return (datetime(1899, 12, 30) + timedelta(days=days)).isoformat(timespec="milliseconds")


def is_catman(path: Path) -> bool:
    """True if the file starts with a catman file ID."""
    with open(path, "rb") as fh:
        head = fh.read(2)
    return len(head) == 2 and struct.unpack("<h", head)[0] in FILE_IDS


def read_catman(path: str | Path) -> Record:
    """Read an HBM catman ``.BIN`` file into a :class:`Record`.

    Channel units are as catman wrote them; each channel gets its sample rate (from dt) and
    catman's -1000000 invalid markers as NaN plus the ``invalid`` mask (counted in
    ``metadata['invalid_count']``). A truncated or non-catman file is a DroptowerError.
    """
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise unreadable_file(path, exc) from None
    try:
        return _parse(path, data)
    except (EOFError, struct.error):
        raise DroptowerError("truncated or corrupt catman file (header runs past the end of the file)",
                             file=path) from None


def _parse(path: Path, data: bytes) -> Record:
    cur = _Cursor(data)
    file_id = cur.unpack("h")
    if file_id not in FILE_IDS:
        raise DroptowerError(f"not a catman binary file (file ID {file_id}, expected 5006..5012)", file=path)
    data_offset = cur.unpack("i")
    comment = cur.string()
    cur.string()  # post-data area offset, as text
    for _ in range(31):
        cur.string()  # reserve strings
    n_channels, _max_length = cur.unpack("hi")
    if n_channels <= 0:
        raise DroptowerError(f"catman file holds {n_channels} channels", file=path)
    length_offsets = cur.unpack(f"{n_channels}i")
    length_offsets = (length_offsets,) if n_channels == 1 else length_offsets

    headers = []
    for i, offset in enumerate(length_offsets):
        cur.pos = offset - 2  # the channel header starts with its location (short)
        location, n_values = cur.unpack("hi")
        name, unit, ch_comment = cur.string(), cur.string(), cur.string()
        fmt, _width, _date, ext_size = cur.unpack("hhdi")
        ext = cur.raw(ext_size)
        if ext_size <= EXPORT_FORMAT_OFFSET or n_values < 0:
            raise DroptowerError(f"channel {i + 1} ('{name}'): unexpected header (extended header of "
                                 f"{ext_size} bytes, {n_values} samples)", file=path)
        t0_days, dt_ms = struct.unpack_from("<dd", ext, 0)
        export = ext[EXPORT_FORMAT_OFFSET]
        if fmt not in (0, 4) or export not in _DTYPES:
            raise DroptowerError(f"channel {i + 1} ('{name}'): unsupported data format {fmt} / "
                                 f"export format {export} (only numeric 8-, 4- and 2-byte data)", file=path)
        headers.append(dict(name=name or f"channel {i + 1}", unit=unit, comment=ch_comment, location=location,
                            n=n_values, export=export, dt_ms=dt_ms, t0=_ole_date(t0_days)))

    channels: dict[str, Channel] = {}
    pos = data_offset
    invalid_count = 0
    for header in headers:
        dtype = _DTYPES[header["export"]]
        n = header["n"]
        if header["export"] == 2:
            lo, hi = struct.unpack_from("<dd", data, pos) if pos + 16 <= len(data) else (None, None)
            if lo is None:
                raise EOFError
            pos += 16
        end = pos + n * dtype.itemsize
        if end > len(data):
            raise DroptowerError(f"truncated catman file: channel '{header['name']}' needs bytes {pos}..{end}, "
                                 f"the file has {len(data)}", file=path)
        raw = np.frombuffer(data, dtype=dtype, count=n, offset=pos)
        pos = end
        if header["export"] == 2:
            values = raw / 32767.0 * (hi - lo) + lo  # HBM: scaled to a 32767 range
        else:
            values = raw.astype(np.float64)
        invalid = values == INVALID_MARKER
        if invalid.any():
            values[invalid] = np.nan
            invalid_count += int(invalid.sum())
        else:
            invalid = None
        rate = _sample_rate(header["dt_ms"])
        name = _unique(header["name"], channels)
        channels[name] = Channel(
            name=name, unit=header["unit"], values=values, sample_rate_hz=rate, invalid=invalid,
            metadata={k: header[k] for k in ("comment", "location", "dt_ms", "t0") if header[k] not in ("", None)}
            | {"precision_bytes": dtype.itemsize})
    metadata = {"file_id": file_id, "invalid_count": invalid_count, "start_time": headers[0]["t0"]}
    if comment:
        metadata["comment"] = comment
    job = _job_description(path)
    if job:
        metadata["job"] = job
    return Record(path=path, channels=channels, metadata=metadata, format="catman binary")


def _job_description(path: Path) -> dict[str, str]:
    """The ``key=value`` lines of catman's ``.TST`` job description beside the file, if any."""
    for suffix in (".TST", ".tst"):
        tst = path.with_suffix(suffix)
        if tst.is_file():
            lines = tst.read_text(encoding="cp1252", errors="replace").splitlines()
            return dict(line.split("=", 1) for line in lines if "=" in line)
    return {}


def _sample_rate(dt_ms: float) -> float | None:
    """Sample rate in Hz from catman's dt (ms); dt is stored as float32 for some channels, so a
    rate within 1e-6 of an integer is taken as that integer."""
    if not dt_ms > 0:
        return None
    rate = 1000.0 / dt_ms
    return float(round(rate)) if abs(rate - round(rate)) < 1e-6 * rate else rate


def _unique(name: str, existing: dict) -> str:
    if name not in existing:
        return name
    k = 2
    while f"{name} ({k})" in existing:
        k += 1
    return f"{name} ({k})"
