"""Read a results table and pick the tests a map may be fitted to.

A results table is what the extractor's tables and :func:`~droptower.campaign.run_campaign` write (CSV,
Parquet, Excel, JSON; one row per test, the extractor's column names), or the paper's Table 4
(``rapp2022_table4_map.csv``), or a lab's own table (read like logs: any delimiter, decimal
comma, units in a row or in brackets, :mod:`droptower.io.table_reader`). The map needs amplitude, frequency, stiffness and damping ratio;
inertia, drop mass, drop height, flags and file are used when present.
"""
from __future__ import annotations

import csv
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from droptower.data import TABLE4_NAME, table4_path
from droptower.errors import DroptowerError, expects, missing_file, no_file_or_preset, readable_file, unreadable_file
from droptower.extract.geometry import FLAGS as GEOMETRY_FLAGS
from droptower.io.table_reader import COMMON_ALIASES, read_table

#: Columns the map is fitted from (the extractor's output names).
REQUIRED = ("amplitude_deg", "frequency_hz", "stiffness_nm_per_deg", "damping_ratio")
#: Extractor flags that make a test's stiffness or damping wrong, so it is left out of the map:
#: a second impact restarts the decay, a poor fit or a window shorter than the paper's three
#: quarters of a period does not determine δ and ω, a clipped channel cuts the peaks, and a
#: geometry that disagrees with the rig's (droptower.extract.geometry: a wrong inertia, lever
#: length or laser radius scales the stiffness or the amplitude).
UNUSABLE_FLAGS = frozenset({"double_impact", "poor_fit", "short_window", "clipping", *GEOMETRY_FLAGS})
#: Lines of a text table searched for its names row when the required columns were not found.
NAMES_SEARCH_LINES = 20


@dataclass(frozen=True)
class ExcludedTest:
    """A test left out of the map: its ``file`` (or ``row N``, 1-based) and the reason."""

    test: str
    reason: str


def read_results(path: str | Path) -> pd.DataFrame:
    """Load a results table: one row per evaluated drop test.

    Parameters
    ----------
    path : str or Path
        A ``.csv`` or ``.parquet`` table (the extractor's results table), a campaign folder
        holding ``results.parquet``, or ``"rapp2022_table4"``: the paper's Table 4, shipped
        with the package.

    Returns
    -------
    DataFrame
        The table, with at least ``amplitude_deg``, ``frequency_hz``, ``stiffness_nm_per_deg``
        (N·m/deg) and ``damping_ratio``.

    Raises
    ------
    DroptowerError
        One line naming the file, for an unreadable file or a missing column.
    """
    path = Path(path)
    if str(path) == TABLE4_NAME and not path.exists():
        path = table4_path()  # the paper's Table 4, shipped with the package
    if path.is_dir():
        if not (path / "results.parquet").is_file():
            raise DroptowerError("a folder without results.parquet (not a campaign folder)", file=path)
        path = path / "results.parquet"
    if not path.is_file():
        if not path.exists() and not path.suffix and len(path.parts) == 1:  # a name, as of a shipped table
            raise no_file_or_preset(path, "table", [TABLE4_NAME])
        raise missing_file(path)
    readable_file(path)
    if _is_own_csv(path):
        # the extractor's own CSV (comma-separated, names in its first line): read as written.
        # The lab's dialect sniffing would take the ';' of its copied `delimiter` column for the separator
        table = _read_own_csv(path)
    else:
        table = read_table(path, COMMON_ALIASES, what="results table")
    misread = _misread_separator(table, path)
    if misread is not None:
        raise DroptowerError(f"the results table's separator was misread: {misread}", file=path)
    check_columns(table, path)
    return table


def _first_line(path: Path) -> str:
    with open(path, encoding="utf-8-sig", errors="replace") as fh:
        for line in fh:
            if line.strip():
                return line
    return ""


def _is_own_csv(path: Path) -> bool:
    """A CSV whose first line, split at commas, holds every :data:`REQUIRED` name: as
    :func:`~droptower.io.tables.write_table` writes the extractor's results."""
    if path.suffix.lower() not in (".csv", ".txt"):
        return False
    names = next(csv.reader([_first_line(path)]), [])
    return all(c in [n.strip() for n in names] for c in REQUIRED)


def _read_own_csv(path: Path) -> pd.DataFrame:
    try:
        return pd.read_csv(path, encoding="utf-8-sig", keep_default_na=True)
    except Exception as exc:  # pandas raises many types for a broken file
        raise unreadable_file(path, f"{type(exc).__name__}: {(str(exc).splitlines() or [''])[0]}",
                              "results table") from None


def _misread_separator(table: pd.DataFrame, path: Path) -> str | None:
    """Why the table lacks its columns when the names are there but were split at the wrong
    separator: a line of the file (of the first :data:`NAMES_SEARCH_LINES`) holding every
    :data:`REQUIRED` name at one separator, while the table was read at another (a column whose
    values hold that other separator, such as a copied ``delimiter`` column, misleads the
    sniffing); or column names that are mostly numbers (a data row taken for the names).
    None where neither."""
    if all(c in table.columns for c in REQUIRED):
        return None
    if path.suffix.lower() in (".csv", ".txt", ".dat", ".tsv", ".asc", ""):
        with open(path, encoding="utf-8-sig", errors="replace") as fh:
            lines = [line for _, line in zip(range(NAMES_SEARCH_LINES), fh)]
        for number, line in enumerate(lines, 1):
            for delimiter in (",", ";", "\t", "|"):
                fields = [f.strip() for f in next(csv.reader([line], delimiter=delimiter), [])]
                if all(c in fields for c in REQUIRED):
                    return (f"line {number} holds the names separated by {delimiter!r}, but the rows do not split "
                            f"alike at it (a value holding another separator, or a line above the names?): "
                            f"write the table with one separator and quoted text, or give the names in the first line")
    names = [str(c) for c in table.columns]
    numbers = [n for n in names if _is_number_text(n)]
    if names and len(numbers) * 2 >= len(names):
        return (f"{len(numbers)} of its {len(names)} column names are numbers (e.g. {numbers[0]!r}): a data row was "
                "taken for the names")
    return None


def _is_number_text(text: str) -> bool:
    try:
        float(text.replace(",", "."))
    except ValueError:
        return False
    return True


def check_columns(table: pd.DataFrame, source: str | Path | None = None) -> None:
    """Raise a one-line error naming the file and every required column it lacks."""
    missing = [c for c in REQUIRED if c not in table.columns]
    if missing:
        raise DroptowerError(
            f"results table lacks column(s) {', '.join(missing)} (has: {', '.join(map(str, table.columns)) or 'none'})",
            file=source,
        )


def flag_list(value: Any) -> list[str]:
    """The flags of one row: a ``;``-separated string (CSV), a list or array (Parquet), or empty.

    A string is split into its flag names whatever the separator, so a list that went through
    ``str()`` (``"['poor_fit', 'clipping']"``) is read right, not kept as one unknown flag."""
    if value is None or (pd.api.types.is_scalar(value) and pd.isna(value)):
        return []
    if isinstance(value, str):
        return re.findall(r"[A-Za-z0-9_]+", value)
    return [str(f) for f in value]


@expects(table="pandas.DataFrame")
def select_tests(table: pd.DataFrame, source: str | Path | None = None) -> tuple[pd.DataFrame, list[ExcludedTest]]:
    """Split a results table into the usable tests and the excluded ones with the reason.

    Each excluded test is named by its ``file``, else its ``log_file``, else "row N" (from 1).
    Excluded: an unusable flag (:data:`UNUSABLE_FLAGS`; a true ``double_impact`` column counts
    as its flag; other flags such as ``double_impact_unchecked`` are warnings and keep the
    test), a missing (NaN) or non-finite value in
    a required column, or a non-positive amplitude, frequency, stiffness or damping ratio
    (eq. 19 and eq. 20 are defined for positive values only).
    """
    check_columns(table, source)
    names = pd.Series([f"row {i + 1}" for i in range(len(table))], index=table.index)
    for column in ("log_file", "file"):  # named by file, else log_file (campaign tables), else the row
        if column in table.columns:
            given = table[column].notna() & (table[column].astype(str).str.strip() != "")
            names = table[column].astype(str).where(given, names)
    flags = [flag_list(v) for v in table["flags"]] if "flags" in table.columns else [[] for _ in range(len(table))]
    if "double_impact" in table.columns:  # the extractor's boolean column says the same as its flag
        second = table["double_impact"].astype(str).str.strip().str.lower().isin(["true", "1", "1.0"])
        for row, hit in zip(flags, second):
            if hit and "double_impact" not in row:
                row.append("double_impact")
    values = table[list(REQUIRED)].apply(pd.to_numeric, errors="coerce").astype(float)
    v = values.to_numpy()
    bad_flag = np.array([any(f in UNUSABLE_FLAGS for f in row) for row in flags], dtype=bool)
    keep = ~bad_flag & np.all(np.isfinite(v), axis=1) & np.all(v > 0, axis=1)
    excluded = []
    failed = (table["status"].astype(str).to_numpy() == "failed") if "status" in table.columns else np.zeros(len(table), bool)
    errors = table["error"].tolist() if "error" in table.columns else [None] * len(table)
    for i in np.flatnonzero(~keep):
        if failed[i]:  # a log that could not be evaluated: its error says why, not its missing values
            excluded.append(ExcludedTest(names.iloc[i], f"failed: {errors[i]}" if isinstance(errors[i], str) else "failed"))
            continue
        reasons = [f"flag {f}" for f in flags[i] if f in UNUSABLE_FLAGS]
        for col, x in zip(REQUIRED, v[i]):
            if not np.isfinite(x):
                reasons.append(f"{col} is {'missing' if np.isnan(x) else x}")
            elif x <= 0:
                reasons.append(f"{col} = {x:g} is not positive")
        excluded.append(ExcludedTest(names.iloc[i], "; ".join(reasons)))
    usable = table.loc[keep].copy()
    usable[list(REQUIRED)] = values.loc[keep]
    return usable, excluded
