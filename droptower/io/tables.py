"""Result tables written in the format their file name asks for.

``write_table(table, path)`` is the one way the project writes a table (plans, map
coefficients, extraction results, validations, campaign results, identification tables): the suffix picks the format — ``.csv``, ``.parquet``, ``.json`` (a list of row
objects, NaN as null) or ``.xlsx`` (openpyxl) — and any other suffix is refused with one
line naming the file, before anything is computed when the caller checks it first with
:func:`check_table_path`. Files are written atomically (a reader never sees half a table).
"""
from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pandas as pd

from droptower.errors import DroptowerError, WriteError, make_folder
from droptower.io.droptower_log import atomic_write


def _csv(table: pd.DataFrame, tmp: str) -> None:
    table.to_csv(tmp, index=False)


def _parquet(table: pd.DataFrame, tmp: str) -> None:
    table.to_parquet(tmp, index=False)


def _json(table: pd.DataFrame, tmp: str) -> None:
    # pandas' to_json writes 1e-05 as 0.0 at its default precision: go through Python floats
    rows = [{k: _json_value(v) for k, v in row.items()} for row in table.to_dict(orient="records")]
    Path(tmp).write_text(json.dumps(rows, indent=1) + "\n")


def _xlsx(table: pd.DataFrame, tmp: str) -> None:
    # openpyxl cannot store pd.NA or lists: empty cells and ';'-joined text instead
    frame = table.astype(object).where(table.notna(), None)
    with open(tmp, "wb") as fh, pd.ExcelWriter(fh, engine="openpyxl") as writer:  # tmp's suffix is not .xlsx
        frame.to_excel(writer, index=False, sheet_name="table")


def _json_value(value: object) -> object:
    if isinstance(value, np.generic):
        value = value.item()
    if value is None or value is pd.NA or (isinstance(value, float) and not math.isfinite(value)):
        return None
    return value


#: suffix -> writer(table, temporary path)
WRITERS: dict[str, Callable[[pd.DataFrame, str], None]] = {
    ".csv": _csv, ".parquet": _parquet, ".json": _json, ".xlsx": _xlsx}
TABLE_SUFFIXES = tuple(WRITERS)


def check_table_path(path: str | Path, option: str | None = None) -> Path:
    """``path`` as a Path if its suffix names a table format; else a one-line error (naming
    ``option``, the parameter or flag that gave it, when given)."""
    path = Path(path)
    if path.suffix.lower() not in WRITERS:
        got = f"'{path.suffix}'" if path.suffix else "no suffix"
        raise DroptowerError(f"unknown table format ({got}); use {', '.join(TABLE_SUFFIXES)}",
                             file=path, where=option)
    return path


def write_table(table: pd.DataFrame, path: str | Path, option: str | None = None) -> Path:
    """Write ``table`` (without its index) to ``path`` in the format of its suffix, atomically;
    the folder is created. List cells are written ``;``-joined, a column mixing text and numbers as text. Returns the path."""
    path = check_table_path(path, option)
    frame = table.copy()
    for name in frame.columns[frame.dtypes == object]:  # noqa: E721 - element-wise dtype comparison, also matching pandas' str dtype
        if any(isinstance(v, (list, tuple)) for v in frame[name]):
            frame[name] = frame[name].map(lambda v: ";".join(map(str, v)) if isinstance(v, (list, tuple)) else v)
        kinds = {type(v) for v in frame[name] if v is not None and v is not pd.NA}
        if str in kinds and len(kinds) > 1:  # mixed metadata (Parquet needs one type per column)
            frame[name] = frame[name].map(lambda v: v if v is None or v is pd.NA else str(v))
    make_folder(path.parent)
    try:
        atomic_write(path, lambda tmp: WRITERS[path.suffix.lower()](frame, tmp))
    except OSError as exc:  # a writer's own OSError outside the temporary file
        raise WriteError.from_os_error(exc, path) from None
    return path
