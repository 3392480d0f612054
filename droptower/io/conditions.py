"""Per-file test conditions: a lab's conditions sheet, or the file names, as SI values per log.

A lab records what it dropped in a sheet with one row per file (file name, lever fixture or
its inertia, drop mass, drop height, preload, specimen, repeat, temperature) or encodes it in
the file names (``L2_m1_h40_rep3.csv``). :func:`read_conditions` reads such a sheet (CSV in
any dialect, ``.xlsx``, ``.parquet``, ``.json``: :mod:`droptower.io.table_reader`), finds its
columns by their common English and German names or by a mapping ``ROLE=COLUMN[:UNIT]``
(like the channels of a log, :mod:`droptower.io.mapping`), converts every unit through pint
(:mod:`droptower.units`; a temperature in degF or K too) and keys the rows by file name or by
path relative to the folder. :func:`conditions_from_names` reads them from file names by a
pattern. :meth:`Conditions.for_path` gives one file's conditions (keys of
:data:`CONDITION_KEYS`, SI), which :class:`droptower.io.logsettings.LogSettings` merges over the
log's own metadata.

A problem of the whole table (unreadable, empty, no file column, a unit that is not one) is a
:class:`DroptowerError`: nothing can be done. A problem of one row (no file name, a file listed
twice, a value that is not a number, a fixture the rig does not have) is one line in
:attr:`Conditions.problems`; the files it concerns fail on their own (their
:meth:`~Conditions.for_path` raises that line) and the rest of the batch goes on.
"""
from __future__ import annotations

import math
import re
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from droptower.errors import DroptowerError, expects, readable_file, unreadable_file
from droptower.io.csvfmt import split_name_unit
from droptower.units import is_unit, normalise_unit

if TYPE_CHECKING:
    from droptower.rig.config import RigConfig

#: the SI keys a file's conditions may carry
CONDITION_KEYS = ("fixture", "inertia_kgm2", "drop_mass_kg", "drop_height_m", "preload_nm",
                  "specimen", "repeat", "temperature_c")
#: roles of a conditions table: the file column and the condition keys
CONDITION_ROLES = ("file", *CONDITION_KEYS)
#: key -> the pint unit its values are converted to (keys not listed are text or counts)
CONDITION_UNITS = {"inertia_kgm2": "kg*m**2", "drop_mass_kg": "kg", "drop_height_m": "m", "preload_nm": "N*m",
                   "temperature_c": "degC"}
#: role -> common column names (lower case, unit stripped, umlauts as ae/oe/ue, separators as blanks)
CONDITION_NAMES: dict[str, tuple[str, ...]] = {
    "file": ("file", "file name", "filename", "files", "log", "log file", "datei", "dateiname", "messdatei",
             "path", "pfad", "messung", "measurement"),
    "fixture": ("fixture", "lever", "lever fixture", "hebel", "hebelvariante", "hebel variante", "arm",
                "schwungmasse", "case", "fall"),
    "inertia_kgm2": ("inertia", "j", "rotating inertia", "moment of inertia", "traegheit", "traegheitsmoment",
                     "massentraegheit", "massentraegheitsmoment"),
    "drop_mass_kg": ("drop mass", "mass", "m1", "fallmasse", "masse", "fallgewicht"),
    "drop_height_m": ("drop height", "height", "h", "fallhoehe", "hoehe"),
    "preload_nm": ("preload", "pre load", "pretorque", "vorlast", "vorspannung", "vorspannmoment"),
    "specimen": ("specimen", "sample", "probe", "pruefling", "coupling", "kupplung", "specimen id"),
    "repeat": ("repeat", "repetition", "rep", "wiederholung", "wdh", "run"),
    "temperature_c": ("temperature", "temp", "temperatur", "t amb", "ambient temperature"),
}
#: pattern field suffix -> unit (``{drop_height_mm}``); the longest suffix first
_PATTERN_UNITS = (("_kgm2", "kg*m**2"), ("_gcm2", "g*cm**2"), ("_knm", "kN*m"), ("_nm", "N*m"), ("_kg", "kg"),
                  ("_g", "g"), ("_mm", "mm"), ("_cm", "cm"), ("_m", "m"), ("_in", "inch"), ("_lb", "lb"),
                  ("_c", "degC"), ("_f", "degF"), ("_k", "K"))
#: relative agreement of a table's inertia with the rig's fixture of the same name
FIXTURE_TOLERANCE = 0.005


def _normalise(name: object) -> str:
    text = split_name_unit(str(name).strip())[0].strip().lower()
    for umlaut, plain in (("ä", "ae"), ("ö", "oe"), ("ü", "ue"), ("ß", "ss")):
        text = text.replace(umlaut, plain)
    return re.sub(r"[\s_\-.]+", " ", text).strip()


def _key(text: str) -> str:
    """A file key as compared: forward slashes, no leading ``./``."""
    return str(PurePosixPath(str(text).strip().replace("\\", "/")))


def _convert(values: pd.Series, unit: str, key: str, source: str) -> pd.Series:
    """``values`` (numbers; NaN kept) from ``unit`` to the key's SI unit; temperatures with
    their offset (degF, K). ValueError with the reason for a unit that is none or of the wrong kind."""
    target = CONDITION_UNITS[key]
    text = normalise_unit(unit) if unit else ""
    if text in ("", "-", "1"):
        return values
    if not is_unit(unit):
        raise ValueError(f"unknown unit '{unit}' in column '{source}' (expected a unit like {target})")
    from droptower.units import _registry

    ureg = _registry()
    try:
        if key == "temperature_c":
            text = {"C": "degC", "°C": "degC", "F": "degF", "°F": "degF"}.get(unit.strip("[]() "), text)
            return pd.Series(ureg.Quantity(values.to_numpy(dtype=float), text).to("degC").magnitude, index=values.index)
        return values * float(ureg.Quantity(1.0, text).to(target).magnitude)
    except Exception:  # pint's errors: wrong dimension, bad syntax
        raise ValueError(f"unit '{unit}' of column '{source}' is not a unit of {key} (expected e.g. {target})") from None


def parse_number(value: Any) -> float | None:
    """A cell as a float (``"1,5"`` read as 1.5), None if empty, ValueError if not a number."""
    if value is None or (isinstance(value, float) and math.isnan(value)) or value is pd.NA:
        return None
    if isinstance(value, (bool, np.bool_)):
        raise ValueError
    if isinstance(value, (int, float, np.integer, np.floating)):
        return float(value)
    text = str(value).strip()
    if not text:
        return None
    return float(text.replace(",", ".") if text.count(",") == 1 and "." not in text else text)


def _text(value: Any) -> str | None:
    if value is None or value is pd.NA or (isinstance(value, float) and math.isnan(value)):
        return None
    if isinstance(value, (float, np.floating)) and float(value).is_integer():
        value = int(value)
    text = str(value).strip()
    return text or None


def _checked(key: str, value: float) -> float | int:
    """A condition value checked for its key (ValueError naming the reason)."""
    if not math.isfinite(value):
        raise ValueError("is not finite")
    if key in ("inertia_kgm2", "drop_mass_kg", "drop_height_m") and value <= 0:
        raise ValueError("must be > 0")
    if key == "temperature_c" and value <= -273.15:
        raise ValueError("is below absolute zero")
    if key == "repeat":
        if not float(value).is_integer():
            raise ValueError("is not a whole number")
        return int(value)
    return float(value)


@dataclass(frozen=True)
class Conditions:
    """Per-file test conditions in SI (keys of :data:`CONDITION_KEYS`), keyed by file.

    source: the table's path, or the file-name pattern; problems: one line per bad row (no file
    name, a file listed twice, a value that is not a number or out of range, a fixture the rig
    does not have), to be reported once by the caller; notes: what was assumed (columns not
    used). Build it with :func:`read_conditions` or :func:`conditions_from_names`.
    """

    source: str
    rows: dict[str, dict[str, Any]] = field(default_factory=dict)
    problems: tuple[str, ...] = ()
    notes: tuple[str, ...] = ()
    errors: dict[str, str] = field(default_factory=dict)   # file key -> why that file has no conditions
    pattern: str | None = None
    fixtures: dict[str, float] = field(default_factory=dict)
    rig_label: str = ""

    def _match(self, path: Path) -> str | None:
        """The key that names ``path``: the longest key equal to the path's last parts, else to
        its last parts without the suffix (a sheet listing ``L2_m1_h40_rep3`` for the ``.csv``)."""
        parts = PurePosixPath(_key(str(path))).parts
        keys = [*self.rows, *self.errors]
        for strip in (False, True):
            best = None
            for key in keys:
                kparts = PurePosixPath(key).parts
                if not kparts or len(kparts) > len(parts):
                    continue
                tail = list(parts[-len(kparts):])
                if strip:
                    tail[-1] = PurePosixPath(tail[-1]).stem
                if tuple(tail) == kparts and (best is None or len(kparts) > len(PurePosixPath(best).parts)):
                    best = key
            if best is not None:
                return best
        return None

    def for_path(self, path: str | Path) -> dict[str, Any]:
        """The conditions of the log at ``path`` (keys of :data:`CONDITION_KEYS`, SI; only those
        given). A file the table does not list, or whose row is bad, raises a
        :class:`DroptowerError` naming the file and the table."""
        path = Path(path)
        if self.pattern is not None:
            return self._from_name(path)
        key = self._match(path)
        if key is None:
            raise DroptowerError(f"not in the conditions table {self.source} (no row names '{path.name}')", file=path)
        if key in self.errors:
            raise DroptowerError(f"conditions table {self.source}: {self.errors[key]}", file=path)
        return dict(self.rows[key])

    def unmatched(self, paths: Iterable[str | Path]) -> list[str]:
        """The table's files that none of ``paths`` is (rows for logs not given), in table order."""
        if self.pattern is not None:
            return []
        used = {self._match(Path(p)) for p in paths}
        return [key for key in [*self.rows, *self.errors] if key not in used]

    def shared_rows(self, paths: Iterable[str | Path]) -> dict[str, str]:
        """Logs of ``paths`` that one row would give its conditions to together (``day1/L2.csv``
        and ``day2/L2.csv`` under a row ``L2.csv``): path -> why it cannot be used (key the
        table by the path relative to the folder). Empty when every row names one log."""
        if self.pattern is not None:
            return {}
        by_key: dict[str, list[str]] = {}
        for p in paths:
            key = self._match(Path(p))
            if key is not None:
                by_key.setdefault(key, []).append(str(p))
        return {p: (f"row '{key}' of the conditions table {self.source} names {len(group)} of the given logs "
                    f"({', '.join(group)}); key the table by the path relative to the folder")
                for key, group in by_key.items() if len(group) > 1 for p in group}

    def _from_name(self, path: Path) -> dict[str, Any]:
        regex, fields = _pattern_regex(self.pattern)
        target = path.name if PurePosixPath(self.pattern).suffix else path.stem
        match = regex.fullmatch(target)
        if match is None:
            raise DroptowerError(f"the file name does not match the conditions pattern '{self.pattern}'", file=path)
        out: dict[str, Any] = {}
        for group, (key, unit) in fields.items():
            raw = match.group(group)
            try:
                if key in CONDITION_UNITS or key == "repeat":
                    number = parse_number(re.sub(r"(?<=\d)p(?=\d)", ".", raw))
                    if number is None:
                        raise ValueError("is empty")
                    if key in CONDITION_UNITS:
                        number = float(_convert(pd.Series([number]), unit, key, f"{{{key}}}").iloc[0])
                    out[key] = _checked(key, number)
                else:
                    out[key] = raw
            except ValueError as exc:
                text = str(exc) if str(exc) and not str(exc).startswith("could not") else "is not a number"
                raise DroptowerError(f"conditions pattern '{self.pattern}': {key} '{raw}' {text}", file=path) from None
        try:
            return _with_fixture(out, self.fixtures, self.rig_label)
        except ValueError as exc:
            raise DroptowerError(f"conditions pattern '{self.pattern}': {exc}", file=path) from None


def _with_fixture(values: dict[str, Any], fixtures: dict[str, float], rig_label: str) -> dict[str, Any]:
    """``values`` with the inertia of its named fixture (the rig's), checked against a given
    one; ValueError naming the problem."""
    name = values.get("fixture")
    if name is None or not fixtures:
        return values
    if name not in fixtures:
        if "inertia_kgm2" in values:
            return values
        raise ValueError(f"fixture '{name}' is not one of the fixtures of rig {rig_label} "
                         f"({', '.join(fixtures)}) and no inertia is given")
    inertia = fixtures[name]
    given = values.get("inertia_kgm2")
    if given is not None and not math.isclose(given, inertia, rel_tol=FIXTURE_TOLERANCE):
        raise ValueError(f"inertia {given:g} kg*m^2 disagrees with fixture '{name}' of rig {rig_label} "
                         f"({inertia:g} kg*m^2)")
    return {**values, "inertia_kgm2": inertia}


def _pattern_regex(pattern: str) -> tuple[re.Pattern, dict[str, tuple[str, str]]]:
    """A file-name pattern (``{fixture}_m{drop_mass_kg}_h{drop_height_mm}``) as a regex and its
    fields: group -> (condition key, unit of the name's values). A field is a key, a key with
    ``:UNIT`` (``{drop_height_m:mm}``) or a key's base with a unit suffix (``{drop_height_mm}``)."""
    fields: dict[str, tuple[str, str]] = {}
    out, pos = [], 0
    for i, m in enumerate(re.finditer(r"\{([^{}]*)\}", pattern)):
        out.append(re.escape(pattern[pos:m.start()]))
        pos = m.end()
        name, _, unit = m.group(1).partition(":")
        name = name.strip()
        key = name if name in CONDITION_KEYS else None
        if key is None:
            for suffix, suffix_unit in _PATTERN_UNITS:
                base = name[: -len(suffix)] if name.endswith(suffix) else None
                candidates = [k for k in CONDITION_UNITS if base and k.rsplit("_", 1)[0] == base]
                if candidates:
                    key, unit = candidates[0], unit or suffix_unit
                    break
        if key is None:
            raise DroptowerError(f"conditions pattern '{pattern}': unknown field '{{{name}}}' (fields: "
                                 f"{', '.join(CONDITION_KEYS)}, or one with its unit, e.g. {{drop_height_mm}})")
        if key in (k for k, _ in fields.values()):
            raise DroptowerError(f"conditions pattern '{pattern}': {key} given twice")
        fields[f"f{i}"] = (key, unit.strip() or (CONDITION_UNITS.get(key, "")))
        numeric = key in CONDITION_UNITS or key == "repeat"
        out.append(f"(?P<f{i}>[-+]?[0-9]+(?:[.,p][0-9]+)?)" if numeric else f"(?P<f{i}>.+?)")
    out.append(re.escape(pattern[pos:]))
    if not fields:
        raise DroptowerError(f"conditions pattern '{pattern}' has no field (e.g. {{drop_height_mm}})")
    return re.compile("".join(out)), fields


def _rig_fixtures(rig: "RigConfig | None") -> tuple[dict[str, float], str]:
    if rig is None:
        return {}, ""
    return dict(rig.fixtures), rig.label


@expects(pattern=str, rig=("droptower.rig.config.RigConfig", type(None)))
def conditions_from_names(pattern: str, *, rig: "RigConfig | None" = None) -> Conditions:
    """Conditions read from each file's name by ``pattern``.

    Parameters
    ----------
    pattern : str
        The file name (without its suffix, unless the pattern has one) with fields in braces:
        a condition key (``{fixture}``, ``{repeat}``, ``{drop_mass_kg}``), a key with a unit
        (``{drop_height_m:mm}``) or a key's base with a unit suffix (``{drop_height_mm}``,
        ``{temperature_c}``); e.g. ``{fixture}_m{drop_mass_kg}_h{drop_height_mm}_rep{repeat}``.
        Numbers may use a decimal comma or ``p`` (``h0p5``).
    rig : RigConfig, optional
        Its named fixtures give a ``{fixture}``'s inertia (kg*m^2).

    Returns
    -------
    Conditions
        ``for_path`` parses a name; a name that does not match raises naming the file.

    Raises
    ------
    DroptowerError
        For a pattern with an unknown field or no field.
    """
    _pattern_regex(pattern)  # refuse a bad pattern before any file is read
    fixtures, label = _rig_fixtures(rig)
    return Conditions(source=f"pattern '{pattern}'", pattern=pattern, fixtures=fixtures, rig_label=label)


def parse_condition_columns(options: Iterable[str]) -> dict[str, str]:
    """``["drop_height_m=Hoehe:mm"]`` -> ``{"drop_height_m": "Hoehe:mm"}``; an unknown role, a
    missing ``=`` or a role given twice is a :class:`DroptowerError`."""
    from droptower.io.mapping import parse_channel_options

    return parse_channel_options([str(text) for text in options], CONDITION_ROLES, what="condition column",
                                 spec="COLUMN")


def _read_frame(path: Path) -> pd.DataFrame:
    """The sheet as read, column names as written (units in them kept, split later)."""
    from droptower.io.table_reader import _read_frame as read_frame

    try:
        frame, units = read_frame(path)
    except DroptowerError as exc:
        raise exc.with_file(path) from None
    except Exception as exc:  # pandas, pyarrow and openpyxl raise many types for a broken file
        raise unreadable_file(path, f"{type(exc).__name__}: {(str(exc).splitlines() or [''])[0]}",
                              "conditions table") from None
    # the reader splits units off the names; put them back so one rule reads them all
    frame.columns = [f"{c} [{units[c]}]" if units.get(c) else str(c) for c in frame.columns]
    return frame


@expects(path=(str, Path), columns=(dict, type(None)), rig=("droptower.rig.config.RigConfig", type(None)))
def read_conditions(path: str | Path, *, columns: dict[str, str] | None = None,
                    rig: "RigConfig | None" = None) -> Conditions:
    """Read a conditions table: one row per log file, keyed by its name or relative path.

    Parameters
    ----------
    path : str or Path
        CSV/ASCII in any dialect (``;`` or tab, decimal comma, lines above the names, a units
        row or units in the names), ``.xlsx``, ``.parquet`` or ``.json``.
    columns : dict, optional
        role -> ``COLUMN`` or ``COLUMN:UNIT`` (roles: ``file`` and :data:`CONDITION_KEYS`); the
        unit overrides the sheet's. Roles not given are found by their common names
        (:data:`CONDITION_NAMES`: ``Datei``, ``Hebel``, ``Traegheit [kg m^2]``,
        ``Fallhoehe [mm]``, ``Temp (degF)``, ...). A column without a unit is in the key's SI unit.
    rig : RigConfig, optional
        Its named fixtures give a ``fixture`` column's inertia (kg*m^2) and check a given one.

    Returns
    -------
    Conditions
        SI values per file; :attr:`Conditions.problems` lists bad rows (each failing only its file).

    Raises
    ------
    DroptowerError
        One line naming the table: unreadable, empty, no file column, no condition column, a
        mapped column it lacks, or a unit that is none or not of its quantity.
    """
    path = Path(path)
    readable_file(path)
    mapping = dict(columns or {})
    unknown = set(mapping) - set(CONDITION_ROLES)
    if unknown:
        raise DroptowerError(f"unknown condition role(s) {', '.join(sorted(unknown))} (roles: "
                             f"{', '.join(CONDITION_ROLES)})", file=path)
    frame = _read_frame(path)
    if frame.shape[0] == 0 or frame.shape[1] == 0:
        raise DroptowerError("empty conditions table: no rows", file=path)
    names = [str(c) for c in frame.columns]
    have = ", ".join(repr(n) for n in names)
    by_norm: dict[str, list[str]] = {}
    for name in names:
        by_norm.setdefault(_normalise(name), []).append(name)
    chosen: dict[str, tuple[str, str]] = {}   # role -> (column, unit)
    for role in CONDITION_ROLES:
        if role in mapping:
            spec = mapping[role]
            column, unit = spec, None
            if column not in names and ":" in spec:
                column, unit = spec.rsplit(":", 1)
            if column not in names:
                # the mapping may name a column without the unit the sheet wrote after it
                found = [n for n in names if split_name_unit(n)[0].strip() == column.strip()]
                if len(found) != 1:
                    raise DroptowerError(f"no column '{column}' for {role} (the table has: {have})", file=path)
                column = found[0]
            chosen[role] = (column, split_name_unit(column)[1] if unit is None else unit)
            continue
        hits = [n for alias in (role, role.replace("_", " "), *CONDITION_NAMES[role]) for n in by_norm.get(alias, [])]
        hits = list(dict.fromkeys(h for h in hits if h not in {c for c, _ in chosen.values()}))
        if len(hits) > 1:
            raise DroptowerError(f"several columns could be the {role} ({', '.join(map(repr, hits))}); choose one "
                                 f"with `columns={{'{role}': 'COLUMN'}}`", file=path)
        if hits:
            chosen[role] = (hits[0], split_name_unit(hits[0])[1])
    if "file" not in chosen:
        raise DroptowerError(f"no file column (the table has: {have}); name it with `columns={{'file': 'COLUMN'}}`",
                             file=path)
    keys = [k for k in CONDITION_KEYS if k in chosen]
    if not keys:
        raise DroptowerError(f"no condition column (the table has: {have}); name them with "
                             f"`columns={{'drop_height_m': 'COLUMN[:UNIT]'}}` (roles: {', '.join(CONDITION_KEYS)})",
                             file=path)
    used = {c for c, _ in chosen.values()}
    unused = [n for n in names if n not in used]
    notes = (f"conditions table {path}: column(s) {', '.join(map(repr, unused))} not used",) if unused else ()

    # per cell: a number (or text) or the reason it is not; units per column (a bad unit: the whole table)
    cells: dict[str, list[Any]] = {}
    for key in keys:
        column, unit = chosen[key]
        raw = frame[column].tolist()
        if key in CONDITION_UNITS or key == "repeat":
            parsed: list[Any] = []
            for value in raw:
                try:
                    parsed.append(parse_number(value))
                except ValueError:
                    parsed.append(ValueError(f"{key} {_text(value)!r} is not a number"))
            if key in CONDITION_UNITS:
                numbers = pd.Series([np.nan if v is None or isinstance(v, ValueError) else v for v in parsed],
                                    dtype=float)
                try:
                    converted = _convert(numbers, unit, key, column)
                except ValueError as exc:
                    raise DroptowerError(str(exc), file=path) from None
                parsed = [v if v is None or isinstance(v, ValueError) else float(c) for v, c in zip(parsed, converted)]
            cells[key] = parsed
        else:
            cells[key] = [_text(v) for v in raw]
    fixtures, label = _rig_fixtures(rig)
    rows: dict[str, dict[str, Any]] = {}
    errors: dict[str, str] = {}
    first_row: dict[str, int] = {}
    problems: list[str] = []
    for i, file_cell in enumerate(frame[chosen["file"][0]].tolist()):
        where = f"row {i + 1}"
        name = _text(file_cell)
        if name is None:
            given = [k for k in keys if cells[k][i] is not None]
            if given:  # a row of values for no file: nothing can use it, say so
                problems.append(f"{path}: {where}: no file name (its conditions are not used)")
            continue
        key = _key(name)
        if key in first_row:
            text = f"listed twice (rows {first_row[key] + 1} and {i + 1})"
            problems.append(f"{path}: {where}: '{name}' {text}")
            errors[key] = f"'{name}' {text}"
            rows.pop(key, None)
            continue
        first_row[key] = i
        values: dict[str, Any] = {}
        try:
            for k in keys:
                value = cells[k][i]
                if isinstance(value, ValueError):
                    raise value
                if value is None:
                    continue
                if k in CONDITION_UNITS or k == "repeat":
                    try:
                        value = _checked(k, value)
                    except ValueError as exc:
                        raise ValueError(f"{k} {value:g} {exc}") from None
                values[k] = value
            values = _with_fixture(values, fixtures, label)
        except ValueError as exc:
            problems.append(f"{path}: {where}: '{name}': {exc}")
            errors[key] = f"{where}: {exc}"
            continue
        rows[key] = values
    if not rows and not errors:
        raise DroptowerError("no row names a file", file=path)
    return Conditions(source=str(path), rows=rows, problems=tuple(problems), notes=notes, errors=errors,
                      fixtures=fixtures, rig_label=label)
