"""The results table of a campaign, assembled from its per-test records.

Columns, in order: the plan (:data:`~droptower.campaign.spec.PLAN_COLUMNS`), the extracted
values under the names of :class:`~droptower.extract.result.ExtractionResult`'s fields (``frequency_hz``,
``amplitude_deg``, ``stiffness_nm_per_deg``, ``damping_ratio``, ..., ``*_std``,
``double_impact``), then ``flags`` (``;``-separated), ``log_file`` (relative to the campaign
folder), ``status`` (``done`` or ``failed``), ``error`` and ``simulation_warnings`` (what the
rig noticed: twist beyond the coupling's limit, a double impact). A failed test has empty
extracted values.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any, Iterable

import numpy as np
import pandas as pd

from droptower.campaign.spec import PLAN_COLUMNS
from droptower.extract.result import TEXT_OUTPUTS
from droptower.io.tables import write_table

TAIL_COLUMNS = ("flags", "log_file", "status", "error", "simulation_warnings")


def assemble(records: list[dict[str, Any]]) -> pd.DataFrame:
    """One row per record, in test order, with the columns of the module docstring."""
    records = sorted(records, key=lambda r: r["test_id"])
    extracted: dict[str, None] = {}  # result names in first-seen order (a dict keeps the order)
    for record in records:
        for name in record.get("result") or {}:
            if name not in PLAN_COLUMNS and name != "flags":
                extracted.setdefault(name)
    rows = []
    for record in records:
        result = record.get("result") or {}
        row = {name: record.get(name) for name in PLAN_COLUMNS}
        row.update({name: result.get(name) for name in extracted})
        row["flags"] = ";".join(result.get("flags") or [])
        row["log_file"] = record.get("log_file")
        row["status"] = record["status"]
        row["error"] = record.get("error") or ""
        row["simulation_warnings"] = ";".join(record.get("simulation_warnings") or [])
        rows.append(row)
    table = pd.DataFrame(rows, columns=[*PLAN_COLUMNS, *extracted, *TAIL_COLUMNS])
    for name in extracted:
        if name == "double_impact":
            table[name] = table[name].astype("boolean")
        elif name in TEXT_OUTPUTS:
            table[name] = table[name].fillna("").astype(str)
        else:
            table[name] = pd.to_numeric(table[name].astype(object).where(table[name].notna(), np.nan))
    return table


def assemble_batches(batches: Iterable[list[dict[str, Any]]]) -> pd.DataFrame:
    """:func:`assemble` of the records of many batches (each in test order, the batches too), one
    batch at a time: memory for the table, not for every record at once. Columns and types as
    :func:`assemble` of all records gives them."""
    parts = [assemble(batch) for batch in batches if batch]
    if len(parts) <= 1:
        return parts[0] if parts else assemble([])
    table = pd.concat(parts, ignore_index=True)
    table = table[[c for c in table.columns if c not in TAIL_COLUMNS] + list(TAIL_COLUMNS)]
    for name in table.columns:
        if len({str(p[name].dtype) if name in p.columns else "absent" for p in parts}) == 1:
            continue
        # the batches typed it differently (all None in one, text in another; absent where no
        # test has a result): type it from all its values, as assemble does
        if name == "double_impact":
            table[name] = table[name].astype("boolean")
        elif name in TEXT_OUTPUTS:
            table[name] = table[name].fillna("").astype(str)
        else:
            table[name] = pd.Series(table[name].tolist(), index=table.index)
            if name not in PLAN_COLUMNS and name not in TAIL_COLUMNS:
                table[name] = pd.to_numeric(table[name].astype(object).where(table[name].notna(), np.nan))
    return table


def write_results(table: pd.DataFrame, parquet: Path, csv: Path) -> None:
    """Write the table as Parquet and CSV, each atomically."""
    write_table(table, parquet)
    write_table(table, csv)
