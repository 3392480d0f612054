"""Tables read as a lab writes them, with the column mapping and unit handling of the logs.

``read_table(path, wanted, columns=...)`` reads results tables, servo results and measured
maps: CSV/ASCII with any delimiter (``,`` ``;`` tab), decimal comma, text lines above the
names row, a units row under the names or units in the names (``Amplitude [°]``), and
Parquet, Excel (``.xlsx``) and JSON tables (a list of row objects). Text columns are kept.

Each wanted column is named with its unit suffix (``amplitude_deg``, ``frequency_hz``,
``storage_stiffness_nm_per_deg``, ``loss_factor``) and found, in this order, as

1. given: ``columns={"amplitude_deg": "Amp:deg"}`` (SOURCE or SOURCE:UNIT, the unit
   overriding the file's);
2. the column of exactly that name;
3. a column whose name, without its unit and lower-cased, is one of the wanted column's
   ``aliases`` (``Frequenz [Hz]`` for ``frequency_hz``);

and converted from the source column's unit (units row, brackets, or ``:UNIT``) to the unit
its name carries, through pint (:mod:`droptower.units`). A column without a unit is taken to
be in the wanted unit. Columns not wanted are kept under their own names.
"""
from __future__ import annotations

import csv
import io
import re
from collections.abc import Iterable
from pathlib import Path

import pandas as pd

from droptower.errors import DroptowerError, readable_file, unreadable_file
from droptower.io.csvfmt import split_name_unit
from droptower.units import conversion_factor, is_unit

#: unit-name suffix -> pint unit (longest first, so ``_nm_per_deg`` wins over ``_deg``)
SUFFIX_UNITS = (("_nm_per_deg", "N*m/deg"), ("_nm_per_rad", "N*m/rad"), ("_kgm2", "kg*m**2"), ("_deg", "deg"),
                ("_rad", "rad"), ("_hz", "Hz"), ("_nm", "N*m"), ("_kg", "kg"), ("_pct", "percent"), ("_s", "s"),
                ("_m", "m"))
DELIMITERS = (";", "\t", ",", "|")
#: names (without unit, lower case) labs give the quantities every table shares
COMMON_ALIASES: dict[str, tuple[str, ...]] = {
    "amplitude_deg": ("amplitude", "amp", "winkelamplitude", "amplitude phi"),
    "frequency_hz": ("frequency", "frequenz", "freq", "f"),
    "inertia_kgm2": ("inertia", "j", "trägheitsmoment", "massenträgheitsmoment"),
    "stiffness_nm_per_deg": ("stiffness", "steifigkeit", "c dyn", "dynamic stiffness c"),
    "damping_ratio": ("damping ratio", "dämpfungsverhältnis", "d ratio"),
}


def wanted_unit(name: str) -> str:
    """The pint unit a column name's suffix says (``""``: dimensionless)."""
    return next((unit for suffix, unit in SUFFIX_UNITS if name.endswith(suffix)), "")


def parse_column_options(options: Iterable[str], option: str = "columns") -> dict[str, str]:
    """``["amplitude_deg=Amp:deg"]`` -> ``{"amplitude_deg": "Amp:deg"}``; a missing ``=`` or a
    name given twice is a one-line error naming ``option``."""
    out: dict[str, str] = {}
    for text in options:
        name, sep, source = text.partition("=")
        if not sep or not name.strip() or not source.strip():
            raise DroptowerError(f"expected NAME=SOURCE[:UNIT], got {text!r}", where=option)
        if name.strip() in out:
            raise DroptowerError(f"column {name.strip()} given twice", where=option)
        out[name.strip()] = source.strip()
    return out


def _normalise(name: str) -> str:
    return re.sub(r"[\s_\-]+", " ", split_name_unit(str(name))[0]).strip().lower()


def _fields(line: str, delimiter: str) -> list[str]:
    return [f.strip() for f in next(csv.reader([line], delimiter=delimiter))]  # quoted fields may hold it


def _layout(lines: list[str]) -> tuple[str, int]:
    """Delimiter and index of the names row: the first delimiter (``;`` first: a decimal-comma
    file splits alike at commas too) that splits every row from the first one of as many fields
    as the last row (> 1) on alike, that first row being all text (the names; lines above it
    are notes)."""
    for delimiter in DELIMITERS:
        counts = [len(_fields(line, delimiter)) for line in lines]
        n = counts[-1]
        if n < 2:
            continue
        names_at = counts.index(n)
        if all(c == n for c in counts[names_at:]) and not any(
                _is_number(f, ",") or _is_number(f, ".") for f in _fields(lines[names_at], delimiter)):
            return delimiter, names_at
    if not any(d in line for line in lines for d in DELIMITERS if d != ",") and not _is_number(lines[0], "."):
        return ",", 0  # one column (a decimal comma or none)
    raise DroptowerError(f"cannot find the columns: no delimiter ({', '.join(map(repr, DELIMITERS))}) splits the "
                         "rows alike under a row of names")


def _read_text(path: Path) -> tuple[pd.DataFrame, dict[str, str]]:
    """A CSV/ASCII table: delimiter and decimal sniffed, lines above the names skipped, units
    from a units row or the names' brackets."""
    raw = path.read_bytes()
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        text = raw.decode("cp1252", errors="replace")  # Windows lab software
    lines = [line for line in text.splitlines() if line.strip()]
    if not lines:
        raise DroptowerError("empty table", file=path)
    delimiter, names_at = _layout(lines)
    body = "\n".join(lines[names_at + 1:])
    decimal = "," if delimiter != "," and re.search(r"\d,\d", body) and not re.search(r"\d\.\d", body) else "."
    names = _fields(lines[names_at], delimiter)
    second = _fields(lines[names_at + 1], delimiter) if len(lines) > names_at + 1 else []
    unit_row = bool(second) and any(second) and all(f in ("-", "") or (is_unit(f) and not _is_number(f, decimal))
                                                    for f in second)
    units = second if unit_row else [""] * len(names)
    frame = pd.read_csv(io.StringIO("\n".join(lines[names_at + 1 + unit_row:])), sep=delimiter, decimal=decimal,
                        header=None, names=range(len(names)), index_col=False, skipinitialspace=True)
    out_names, out_units = [], {}
    for name, unit in zip(names, units):
        if not unit:
            name, unit = split_name_unit(name)
        out_names.append(name)
        out_units[name] = unit
    frame.columns = out_names
    return frame, out_units


def _is_number(text: str, decimal: str) -> bool:
    try:
        float(text.replace(decimal, "."))
    except ValueError:
        return False
    return True


def _read_frame(path: Path) -> tuple[pd.DataFrame, dict[str, str]]:
    suffix = path.suffix.lower()
    if suffix in (".csv", ".txt", ".dat", ".tsv", ".asc", ""):
        return _read_text(path)
    if suffix in (".parquet", ".pq"):
        frame = pd.read_parquet(path)
    elif suffix == ".xlsx":
        frame = pd.read_excel(path, engine="openpyxl")
    elif suffix == ".json":
        frame = pd.read_json(path, orient="records")
    else:
        raise DroptowerError(f"unsupported table format '{path.suffix}' (use .csv, .parquet, .xlsx or .json)",
                             file=path)
    units = {}
    for name in list(frame.columns):
        base, unit = split_name_unit(str(name))
        if unit and is_unit(unit):
            frame = frame.rename(columns={name: base})
            units[base] = unit
    return frame, units


def _factor(source_unit: str, target: str, path: Path, column: str) -> float:
    try:
        return conversion_factor(source_unit, target)
    except ValueError as exc:
        raise DroptowerError(str(exc), file=path, where=f"column '{column}'") from None


def read_table(path: str | Path, wanted: dict[str, tuple[str, ...]], columns: dict[str, str] | None = None,
               what: str = "table") -> pd.DataFrame:
    """The table at ``path`` with each ``wanted`` column (name -> aliases) found and converted as
    the module docstring says; wanted columns not found are simply absent (the caller names
    what it needs). Unreadable files and bad units are one-line errors naming the file."""
    path = Path(path)
    readable_file(path)
    try:
        frame, units = _read_frame(path)
    except DroptowerError as exc:
        raise exc.with_file(path) from None
    except Exception as exc:  # pandas, pyarrow and openpyxl raise many types for a broken file
        raise unreadable_file(path, f"{type(exc).__name__}: {(str(exc).splitlines() or [''])[0]}", what) from None
    columns = dict(columns or {})
    unknown = set(columns) - set(wanted)
    if unknown:
        raise DroptowerError(f"unknown column name(s) {', '.join(sorted(unknown))} (names: {', '.join(wanted)})",
                             file=path)
    normalised = {_normalise(c): c for c in frame.columns}
    renames, factors = {}, {}
    for name, aliases in wanted.items():
        unit = None
        if name in columns:
            source = columns[name]
            if source not in frame.columns and ":" in source:
                source, unit = source.rsplit(":", 1)
            if source not in frame.columns:
                raise DroptowerError(f"no column '{source}' for {name} (the file has: "
                                     f"{', '.join(map(str, frame.columns))})", file=path)
        elif name in frame.columns:
            source = name
        else:
            source = next((normalised[a] for a in (name.replace("_", " "), *aliases) if a in normalised), None)
            if source is None:
                continue
        renames[source] = name
        factors[name] = _factor(units.get(source, "") if unit is None else unit, wanted_unit(name), path, source)
    table = frame.rename(columns=renames)
    for name, factor in factors.items():
        if factor != 1.0:
            table[name] = pd.to_numeric(table[name], errors="coerce") * factor
    return table
