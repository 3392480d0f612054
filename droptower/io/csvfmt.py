"""CSV / ASCII logs: delimiter, decimal comma, header lines and unit row, given or sniffed.

Handles what lab software writes as text:

- plain CSV (``,`` ``;`` tab or blanks), decimal point or decimal comma;
- header lines above the column names (catman ASCII exports, lab notes), kept as metadata;
- a row of units under the names (``s;N;deg``), or units in brackets in the names
  (``Torque [N*m]``, ``Winkel (deg)``);
- MTS 793 ``.dat`` files: the first line ``MTS793|progName|language|version|iDelim|sDecimal|
  ...`` gives the delimiter (0 blank, 1 comma, 2 tab) and the decimal separator; names and
  units rows follow, and the header block may be repeated for each data buffer.

Sniffing looks at the first lines only: the data starts at the first run of purely numeric rows
with a constant number of fields; the row above is the unit row if every entry is a unit pint
knows, the row above that (or above the data) the names. Values are parsed by pandas' C parser
(shortest-text floats read back bit-exact). Options given explicitly win over sniffing.
"""
from __future__ import annotations

import io
import re
from pathlib import Path
from typing import Any

import numpy as np

from droptower.errors import DroptowerError, unreadable_file
from droptower.io.channels import Channel, Record
from droptower.units import is_unit

SNIFF_LINES = 200
_UNIT_IN_NAME = re.compile(r"^(.*?)\s*[\[(]\s*([^\])]*?)\s*[\])]\s*$")
_MTS_DELIMS = {"0": " ", "1": ",", "2": "\t"}
CATMAN_INVALID = -1_000_000.0


def _decode(data: bytes, encoding: str | None) -> str:
    if encoding:
        return data.decode(encoding)
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError:
        return data.decode("cp1252", errors="replace")  # Windows lab software


def _split(line: str, delimiter: str) -> list[str]:
    if delimiter == " ":
        return line.split()
    return [field.strip().strip('"') for field in line.rstrip("\r\n").split(delimiter)]


def _is_number(text: str, decimal: str) -> bool:
    if decimal != ".":
        text = text.replace(decimal, ".")
    try:
        float(text)
    except ValueError:
        return False
    return True


def _numeric_row(fields: list[str], decimal: str) -> bool:
    filled = [f for f in fields if f]
    return bool(filled) and all(_is_number(f, decimal) for f in filled)


def _sniff_delimiter(lines: list[str]) -> str:
    """The delimiter that splits the most of the last 30 sniffed lines (mostly data, cheap to
    test) into the same number (>1) of numbers."""
    lines = lines[-30:]
    best, best_rows = ",", 0
    for delim in ("\t", ";", ",", "|", " "):
        decimal = "." if delim == "," else ","
        counts = [len(fields) for fields in (_split(line, delim) for line in lines)
                  if len(fields) > 1 and _numeric_row([f.replace(decimal, ".") for f in fields], ".")]
        rows = max((counts.count(c) for c in set(counts)), default=0)
        if rows > best_rows:
            best, best_rows = delim, rows
    return best


def _sniff_decimal(lines: list[str], delimiter: str) -> str:
    if delimiter == ",":
        return "."
    tail = " ".join(lines[-20:])
    return "," if re.search(r"\d,\d", tail) and not re.search(r"\d\.\d", tail) else "."


def _data_start(lines: list[str], delimiter: str, decimal: str) -> tuple[int, int]:
    """Index and field count of the first run of numeric rows with one field count: at least
    2 rows (MTS buffers may be short and followed by a text block header), or the last row."""
    rows = [(i, _split(line, delimiter)) for i, line in enumerate(lines) if line.strip()]
    for k, (i, fields) in enumerate(rows):
        if not _numeric_row(fields, decimal):
            continue
        run = 1
        for _, more in rows[k + 1:k + 2]:
            if len(more) != len(fields) or not _numeric_row(more, decimal):
                break
            run += 1
        if run >= 2 or k + run == len(rows):
            return i, len(fields)
    raise DroptowerError("no numeric data rows found in the first lines (is this a log file?)")


def split_name_unit(name: str) -> tuple[str, str]:
    """``"Torque [N*m]"`` -> ``("Torque", "N*m")``; ``("Torque", "")`` if no unit in brackets."""
    match = _UNIT_IN_NAME.match(name)
    return (match.group(1), match.group(2)) if match else (name, "")


def _names_and_units(names: list[str], units: list[str] | None) -> tuple[list[str], list[str]]:
    out_names, out_units = [], []
    for i, name in enumerate(names):
        unit = units[i].strip("[]() ") if units is not None and i < len(units) else ""
        if not unit:
            name, unit = split_name_unit(name)
        out_names.append(name or f"column {i + 1}")
        out_units.append(unit)
    return out_names, out_units


def read_csv_log(path: str | Path, *, delimiter: str | None = None, decimal: str | None = None,
                 header_lines: int | None = None, unit_row: bool | None = None, encoding: str | None = None,
                 invalid_marker: float | None = None) -> Record:
    """Read a CSV/ASCII log into a :class:`Record` (units as written; no time base attached).

    delimiter: field separator (``"\\t"``, ``";"``, ``","``, ``" "`` for blanks); decimal:
    ``"."`` or ``","``; header_lines: lines above the names row; unit_row: whether a units
    row follows the names; encoding: text encoding (UTF-8, else cp1252); invalid_marker: a
    value meaning "no valid sample" (default: catman's -1000000 if the header mentions catman).
    Anything not given is sniffed.
    """
    path = Path(path)
    try:
        text = _decode(path.read_bytes(), encoding)
    except (OSError, UnicodeDecodeError, LookupError) as exc:
        raise unreadable_file(path, exc) from None
    try:
        return _parse(path, text, delimiter, decimal, header_lines, unit_row, invalid_marker)
    except DroptowerError as exc:
        raise exc.with_file(path) from None


def _parse(path: Path, text: str, delimiter, decimal, header_lines, unit_row, invalid_marker) -> Record:
    """Sniff the format and separators, locate the names and units rows, read the data rows,
    convert the numeric columns to channels."""
    head = [line.rstrip("\r") for line in text.split("\n", SNIFF_LINES + 1)[:SNIFF_LINES]]
    metadata: dict[str, Any] = {}
    mts = bool(head) and head[0].startswith("MTS793|")
    if mts:
        metadata["mts793_header"] = head[0]
        delimiter, decimal = _mts_separators(head[0], delimiter, decimal)
    delimiter, decimal = _separators(head, header_lines, delimiter, decimal)
    names_at, names, units, start, n_fields = _header(head, header_lines, unit_row, delimiter, decimal)
    names, unit_list = _names_and_units(names, units)
    header_text = [line for line in head[:names_at] if line.strip()]
    if header_text:
        metadata["header"] = header_text
    if invalid_marker is None and "catman" in "\n".join(head[:start]).lower():
        invalid_marker = CATMAN_INVALID
    frame = _read_rows(text, start, n_fields, delimiter, decimal, mts)
    channels, skipped = _channels(frame, names, unit_list, invalid_marker)
    if skipped:
        metadata["skipped_text_columns"] = skipped
    metadata.update(delimiter=delimiter, decimal=decimal, header_lines=names_at)
    return Record(path=path, channels=channels, metadata=metadata, format="MTS 793" if mts else "csv")


def _mts_separators(first_line: str, delimiter, decimal) -> tuple[str | None, str | None]:
    """An MTS 793 export names its delimiter and decimal separator in its first line."""
    fields = first_line.split("|")
    if delimiter is None and len(fields) > 4:
        delimiter = _MTS_DELIMS.get(fields[4])
    if decimal is None and len(fields) > 5 and fields[5] in (".", ","):
        decimal = fields[5]
    return delimiter, decimal


def _separators(head: list[str], header_lines, delimiter, decimal) -> tuple[str, str]:
    """Delimiter and decimal separator: as given, else sniffed from the lines below the header."""
    if header_lines is not None and (header_lines < 0 or header_lines >= len(head)):
        raise DroptowerError(f"header_lines={header_lines} is outside the file's first {len(head)} lines")
    body = head[header_lines:] if header_lines is not None else head
    if delimiter is None:
        delimiter = _sniff_delimiter(body)
    if decimal is None:
        decimal = _sniff_decimal(body, delimiter)
    if delimiter == decimal:
        raise DroptowerError(f"delimiter and decimal separator are both {delimiter!r}")
    return delimiter, decimal


def _header(head: list[str], header_lines, unit_row, delimiter: str, decimal: str):
    """(line of the names, names, units or None, first data line, number of fields)."""
    if header_lines is not None:
        return _header_at(head, header_lines, unit_row, delimiter, decimal)
    return _header_above_data(head, unit_row, delimiter, decimal)


def _header_at(head: list[str], names_at: int, unit_row, delimiter: str, decimal: str):
    """The names at the given line; the units in the next one if asked, or if it reads as units."""
    names = _split(head[names_at], delimiter)
    if unit_row is None:
        below = _split(head[names_at + 1], delimiter) if names_at + 1 < len(head) else []
        unit_row = not _numeric_row(below, decimal) and all(is_unit(f) for f in below)
    units = _split(head[names_at + 1], delimiter) if unit_row else None
    return names_at, names, units, names_at + 1 + bool(unit_row), len(names)


def _header_above_data(head: list[str], unit_row, delimiter: str, decimal: str):
    """The rows right above the first data row that have as many fields as the data: the last
    one the units if it reads as units (and a names row is right above it), else the names."""
    start, n_fields = _data_start(head, delimiter, decimal)
    above = [(i, _split(head[i], delimiter)) for i in range(start) if head[i].strip()]
    fitting = [(i, fields) for i, fields in above if len(fields) == n_fields]
    names = units = None
    names_at = start
    if fitting:
        i_last, last = fitting[-1]
        adjacent = len(fitting) >= 2 and above[-1][0] == i_last and above[-2][0] == fitting[-2][0]
        if unit_row is None:
            unit_row = adjacent and all(is_unit(f) for f in last)
        if unit_row:
            if not adjacent:
                raise DroptowerError("unit row requested but there is no names row right above it")
            (names_at, names), units = fitting[-2], last
        else:
            names_at, names = i_last, last
    elif unit_row:
        raise DroptowerError("unit row requested but no names and units rows were found")
    return names_at, names or [f"column {i + 1}" for i in range(n_fields)], units, start, n_fields


def _read_rows(text: str, start: int, n_fields: int, delimiter: str, decimal: str, mts: bool):
    """The data rows from line ``start`` on, as a DataFrame of ``n_fields`` columns."""
    import pandas as pd

    data_text = text.split("\n", start)[-1] if start else text
    if mts:
        # MTS repeats "Data Acquisition", names and units rows before each buffer: keep numbers
        data_text = "\n".join(line for line in data_text.split("\n")
                              if line.strip() and _numeric_row(_split(line, delimiter)[:1], decimal))
    sep = r"\s+" if delimiter == " " else delimiter
    try:
        return pd.read_csv(io.StringIO(data_text), sep=sep, decimal=decimal, header=None,
                           names=range(n_fields), engine="c", skip_blank_lines=True, index_col=False)
    except (ValueError, pd.errors.ParserError) as exc:
        raise DroptowerError(f"bad data rows: {str(exc).splitlines()[0]}") from None


def _channels(frame, names: list[str], unit_list: list, invalid_marker) -> tuple[dict[str, Channel], list[str]]:
    """Numeric columns as channels (the invalid marker as NaN, flagged); the text columns' names."""
    import pandas as pd

    channels: dict[str, Channel] = {}
    skipped = []
    for i, name in enumerate(names):
        column = frame[i]
        if column.dtype.kind not in "fiu":
            bad = pd.to_numeric(column, errors="coerce").isna() & column.notna()
            row = int(np.flatnonzero(bad.to_numpy())[0])
            if bad.sum() < len(column):  # a number column with a stray text value
                raise DroptowerError(f"column '{name}': non-numeric value {column.iloc[row]!r} at data row {row + 1}")
            skipped.append(name)
            continue
        values = column.to_numpy(dtype=np.float64)
        invalid = None
        if invalid_marker is not None:
            invalid = values == invalid_marker
            if invalid.any():
                values = values.copy()
                values[invalid] = np.nan
            else:
                invalid = None
        key = name if name not in channels else f"{name} ({i + 1})"
        channels[key] = Channel(name=key, unit=unit_list[i], values=values, invalid=invalid)
    if not channels:
        raise DroptowerError("no numeric columns")
    return channels, skipped
