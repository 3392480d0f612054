"""The project's own log format: what the virtual rig writes, read like any real log.

Two containers, chosen by the file suffix, with the same columns:

``.csv`` -- UTF-8 text::

    # droptower-log 1
    # inertia_kgm2 = 0.0123
    # coupling = "BoWex-M-32"
    # seed = 7
    time_s,angle_rad,torque_nm,impact_force_n,laser_distance_m
    0.0,1.5e-05,0.0021,0.0,0.000312
    ...

The first line identifies the format and its version. Each following ``# key = value`` line is
one metadata entry, the value written as JSON (numbers, strings, lists, objects). Then a header
row of column names and the values, floats written with the shortest text that reads back
bit-exact (like Python ``repr``; ``nan`` for a missing value).

``.parquet`` -- the same columns (float64); the metadata is stored as JSON in the Arrow schema
metadata under the key ``droptower``: ``{"format": "droptower-log", "version": 1,
"metadata": {...}}``. A *compact* log (``write_log(..., compact=True)``, what a campaign
writes) keeps ``time_s`` in float64 and stores the other channels as float32, compressed with
zstd after Parquet's byte-stream split: about 50 kB instead of 180 kB for a 0.1 s record at
38.4 kHz. float32 keeps about 7 significant digits, far below the noise of any of the rig's
sensors (docs/campaigns_at_scale.md#compact-logs); readers get float64 either way.

Column names carry their unit as a suffix (see :data:`SUFFIX_UNITS`): ``time_s`` (s),
``angle_rad`` (rad), ``torque_nm`` (N*m), ``impact_force_n`` (N), ``laser_distance_m`` (m),
``..._deg`` (deg), ``..._mm`` (mm). The first column is the time in seconds. Files are written
atomically (a temporary file in the same folder, then :func:`os.replace`), so a crashed run
never leaves a half-written log.
"""
from __future__ import annotations

import io
import json
import os
import tempfile
from pathlib import Path
from typing import Any, Callable

import numpy as np

from droptower.errors import DroptowerError, WriteError, expects, make_folder, unreadable_file
from droptower.io.channels import Channel, Record

MAGIC = "# droptower-log 1"
PARQUET_KEY = b"droptower"
TIME_COLUMN = "time_s"
#: Arrow's thread pools stay unused: a log is small, and a pool's native threads still running
#: when the interpreter exits made ``extract`` abort now and then ("terminate called without an
#: active exception", exit 134, after its output was complete; apache/arrow#34314).
ARROW_THREADS = False

#: Unit implied by a column name's suffix, longest suffix first (``_nm`` before ``_m``).
SUFFIX_UNITS: tuple[tuple[str, str], ...] = (
    ("_rad", "rad"), ("_deg", "deg"), ("_nm", "N*m"), ("_mm", "mm"), ("_ms", "ms"),
    ("_hz", "Hz"), ("_kn", "kN"), ("_s", "s"), ("_n", "N"), ("_m", "m"),
)


def unit_from_name(name: str) -> str:
    """The unit a column name's suffix implies (``"torque_nm"`` -> ``"N*m"``), or ``""``."""
    lower = name.lower()
    for suffix, unit in SUFFIX_UNITS:
        if lower.endswith(suffix) and len(lower) > len(suffix):
            return unit
    return ""


def _json_default(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"metadata value of type {type(value).__name__} cannot be written as JSON")


def current_umask() -> int:
    """The process's file-mode creation mask, read without changing it where the OS allows."""
    try:
        with open("/proc/self/status") as fh:  # Linux >= 4.7: no window in which the mask is 0
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def atomic_write(path: str | Path, write: Callable[[str], None]) -> None:
    """Write ``path`` all at once: ``write(tmp)`` fills a temporary file in the same folder, which
    then replaces ``path`` by :func:`os.replace` (atomic on one file system), so a reader never
    sees a half-written file and an interrupted write leaves the old file; the temporary file
    is removed if ``write`` fails. The file gets the mode a plain ``open`` would give it (0666
    less the umask; the temporary file is created 0600). A write the system refuses (full disk,
    no permission, read-only file system) is a one-line :class:`~droptower.errors.WriteError` naming ``path``."""
    path = Path(path)
    try:
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    except OSError as exc:
        raise WriteError.from_os_error(exc, path) from None
    os.close(fd)
    try:
        write(tmp)
        os.chmod(tmp, 0o666 & ~current_umask())
        os.replace(tmp, path)
    except BaseException as exc:
        Path(tmp).unlink(missing_ok=True)
        if isinstance(exc, OSError):
            raise WriteError.from_os_error(exc, path) from None
        raise


def save_figure(fig: Any, path: str | Path, dpi: int) -> Path:
    """Write a matplotlib figure to ``path`` (format from the suffix) as :func:`atomic_write`
    writes; a refused write or a suffix matplotlib cannot write blames ``path``."""
    path = Path(path)
    make_folder(path.parent)
    try:
        atomic_write(path, lambda tmp: fig.savefig(tmp, dpi=dpi, format=path.suffix.lstrip(".").lower() or "png"))
    except ValueError as exc:  # a suffix matplotlib does not write
        raise DroptowerError(f"cannot write ({exc})", file=path) from None
    return path


@expects(channels="builtins.dict", metadata="builtins.dict")
def write_log(path: str | Path, time_s: np.ndarray, channels: dict[str, np.ndarray], metadata: dict[str, Any],
              compact: bool = False) -> Path:
    """Write one test as a droptower log (``.csv`` or ``.parquet``); returns the path.

    time_s: (N,) time in s; channels: column name (with unit suffix) -> (N,) values;
    metadata: JSON-serialisable test metadata (numpy scalars are accepted); compact: the
    channels (not the time) as float32, and a Parquet file compressed (zstd, byte-stream split).
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".csv", ".parquet"):
        raise DroptowerError(f"unknown log suffix '{path.suffix}' (use .csv or .parquet)", file=path)
    columns = {TIME_COLUMN: np.asarray(time_s, dtype=np.float64)}
    for name, values in channels.items():
        if name == TIME_COLUMN or not name or any(c in name for c in ",\n\r\"#"):
            raise DroptowerError(f"invalid channel name {name!r}", file=path)
        columns[name] = np.asarray(values, dtype=np.float32 if compact else np.float64)
        if columns[name].shape != columns[TIME_COLUMN].shape:
            raise DroptowerError(
                f"channel '{name}' has shape {columns[name].shape}, time has {columns[TIME_COLUMN].shape}", file=path)
    make_folder(path.parent)

    if suffix == ".csv":
        lines = [MAGIC]
        for key, value in metadata.items():
            if not isinstance(key, str) or "=" in key or "\n" in key:
                raise DroptowerError(f"invalid metadata key {key!r}", file=path)
            lines.append(f"# {key} = {json.dumps(value, default=_json_default, ensure_ascii=False)}")
        lines.append(",".join(columns))
        header = ("\n".join(lines) + "\n").encode("utf-8")

        def write(tmp: str) -> None:
            import pyarrow as pa
            import pyarrow.csv as pcsv

            # Arrow writes the shortest text that reads back bit-exact (like repr), ~10x faster
            with open(tmp, "wb") as fh:
                fh.write(header)
                pcsv.write_csv(pa.table(columns), fh, pcsv.WriteOptions(include_header=False, quoting_style="none"))
    else:
        import pyarrow as pa
        import pyarrow.parquet as pq

        meta = {"format": "droptower-log", "version": 1, "metadata": metadata}
        table = pa.table(columns).replace_schema_metadata(
            {PARQUET_KEY: json.dumps(meta, default=_json_default).encode()})

        # float32 bytes split by significance compress well (the exponent bytes barely change)
        options = {"compression": "zstd", "use_dictionary": False, "use_byte_stream_split": True} if compact else {}

        def write(tmp: str) -> None:
            pq.write_table(table, tmp, **options)

    atomic_write(path, write)
    return path


def is_droptower_csv(path: Path) -> bool:
    """True if the file starts with the droptower-log magic line."""
    with open(path, "rb") as fh:
        return fh.readline().rstrip(b"\r\n").decode("utf-8", "replace").startswith("# droptower-log")


def _record(path: Path, columns: dict[str, np.ndarray], metadata: dict[str, Any], fmt: str) -> Record:
    if TIME_COLUMN not in columns:
        raise DroptowerError(f"no '{TIME_COLUMN}' column (has: {', '.join(columns) or 'none'})", file=path)
    time = columns[TIME_COLUMN]
    channels = {name: Channel(name=name, unit=unit_from_name(name), values=values, time_s=time)
                for name, values in columns.items()}
    return Record(path=path, channels=channels, metadata=metadata, format=fmt)


def read_log(path: str | Path) -> Record:
    """Read a droptower log (``.csv`` or ``.parquet``) into a :class:`Record`.

    Parameters
    ----------
    path : str or Path
        A log as :func:`write_log` (and :meth:`~droptower.rig.simulate.DropResult.write_log`, a campaign) writes it.

    Returns
    -------
    Record
        Its channels, each on the ``time_s`` column as time base, with the unit its name ends
        in (``angle_rad``, ``torque_nm``), and the log's metadata (``inertia_kgm2``, ...).

    Raises
    ------
    DroptowerError
        One line naming the file, for a missing, unreadable or malformed log.
    """
    path = Path(path)
    try:
        if path.suffix.lower() == ".parquet":
            return _read_parquet(path)
        return _read_csv(path)
    except DroptowerError as exc:
        raise exc.with_file(path) from None
    except RecursionError:  # json: metadata nested thousands deep
        raise unreadable_file(path, "metadata nested too deeply", "droptower log") from None
    except (OSError, ValueError, UnicodeDecodeError) as exc:
        raise unreadable_file(path, exc, "droptower log") from None


def _read_csv(path: Path) -> Record:
    import pyarrow as pa
    import pyarrow.csv as pcsv

    data = path.read_bytes()
    stream = io.BytesIO(data)
    first = stream.readline().decode("utf-8").rstrip("\r\n")
    if first.split()[:2] != ["#", "droptower-log"]:
        raise DroptowerError("not a droptower log (first line is not '# droptower-log 1')")
    if first != MAGIC:
        raise DroptowerError(f"unsupported droptower-log version: {first[2:]!r}")
    metadata: dict[str, Any] = {}
    lineno = 1
    while True:
        pos = stream.tell()
        line = stream.readline().decode("utf-8")
        lineno += 1
        if not line.startswith("#"):
            stream.seek(pos)
            break
        key, sep, value = line[1:].partition("=")
        if not sep:
            raise DroptowerError("metadata line is not '# key = value'", where=f"line {lineno}")
        try:
            metadata[key.strip()] = json.loads(value)
        except json.JSONDecodeError as exc:
            raise DroptowerError(f"metadata value is not JSON ({exc.msg})", where=f"line {lineno}") from None
    try:
        table = pcsv.read_csv(stream, read_options=pcsv.ReadOptions(use_threads=ARROW_THREADS),
                              convert_options=pcsv.ConvertOptions(column_types=None))
    except pa.ArrowInvalid as exc:
        raise DroptowerError(f"bad data rows: {str(exc).splitlines()[0]}") from None
    columns = {}
    for name in table.column_names:
        column = table.column(name)
        if not pa.types.is_floating(column.type) and not pa.types.is_integer(column.type):
            raise DroptowerError(f"column '{name}' is not numeric")
        columns[name] = column.to_numpy().astype(np.float64, copy=False)
    return _record(path, columns, metadata, "droptower-log csv")


def parquet_metadata(path: Path) -> dict[str, Any] | None:
    """The droptower metadata block of a Parquet file, or None if it is not a droptower log."""
    import pyarrow.parquet as pq

    meta = pq.read_schema(path).metadata or {}
    if PARQUET_KEY not in meta:
        return None
    return json.loads(meta[PARQUET_KEY])


def _read_parquet(path: Path) -> Record:
    import pyarrow.parquet as pq

    with pq.ParquetFile(path) as parquet:  # footer, metadata and columns from one open (read_table: ~3x the CPU)
        meta = parquet.schema_arrow.metadata or {}
        block = json.loads(meta[PARQUET_KEY]) if PARQUET_KEY in meta else None
        if not isinstance(block, dict) or block.get("format") != "droptower-log":
            raise DroptowerError("not a droptower log (no 'droptower' schema metadata)")
        if block.get("version") != 1:
            raise DroptowerError(f"unsupported droptower-log version {block.get('version')!r}")
        table = parquet.read(use_threads=ARROW_THREADS)
    columns = {name: table.column(name).to_numpy().astype(np.float64, copy=False) for name in table.column_names}
    return _record(path, columns, dict(block.get("metadata", {})), "droptower-log parquet")
