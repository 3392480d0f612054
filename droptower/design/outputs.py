"""What a designed campaign hands to the lab: a test-plan TOML and a randomised run sheet."""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import tomli_w

from droptower.io.droptower_log import atomic_write

#: Columns of a design's printed condition table (all are in its ``to_dict()``).
TABLE_COLUMNS = ["case", "drop_mass_kg", "drop_height_m", "preload_nm", "repeats", "amplitude_deg",
                 "frequency_hz", "damping_ratio", "peak_torque_nm", "min_clearance_mm"]

#: Columns of the lab's run sheet, in order.
SHEET_COLUMNS = ["run", "block", "case", "inertia_kgm2", "drop_mass_kg", "drop_height_m", "preload_nm", "repeat",
                 "predicted_amplitude_deg", "predicted_frequency_hz", "operator_notes"]


def doe_document(conditions: pd.DataFrame, name: str, description: str, base_seed: int = 0) -> dict[str, Any]:
    """Designed conditions (one row per lever, mass, height and preload, with ``repeats``) as
    the DOE TOML format holds them (:func:`~droptower.campaign.run_campaign` runs it as its ``doe``): one group per lever
    and drop mass with its own heights; the preloads for all. Equal repeats everywhere are the
    plan's ``repeats``; otherwise a height is listed once per repeat (the format adds them up)."""
    preloads = sorted({float(p) for p in conditions["preload_nm"]})
    repeats = conditions["repeats"].astype(int)
    uniform = repeats.nunique() == 1
    groups = []
    for (case, j, m), g in conditions.groupby(["case", "inertia_kgm2", "drop_mass_kg"], sort=True):
        per_height = g.groupby("drop_height_m")["repeats"].max()
        heights = [float(h) for h, n in per_height.items() for _ in range(1 if uniform else int(n))]
        groups.append({"name": f"{case}, {m:g} kg", "inertia_kgm2": float(j), "drop_mass_kg": float(m),
                       "heights_m": heights})
    return {"name": name, "description": description, "source": "droptower design", "base_seed": int(base_seed),
            "repeats": int(repeats.iloc[0]) if uniform else 1,
            "heights_m": sorted({h for g in groups for h in g["heights_m"]}), "preloads_nm": preloads,
            "group": groups}


def coverage_description(design: Any) -> str:
    """The plan file's description of a design (:class:`~droptower.design.choose.Design`): its
    target (deg x Hz), conditions, tests and the share of the target the realised tests cover."""
    t = design.target
    return (f"designed by droptower design for {t.amplitude_deg[0]:g}-{t.amplitude_deg[1]:g} deg x "
            f"{t.frequency_hz[0]:g}-{t.frequency_hz[1]:g} Hz: {design.n_conditions} conditions, "
            f"{design.n_tests} tests, {100 * design.covered_fraction:.0f} % of the target covered")


def write_doe(conditions: pd.DataFrame, path: str | Path, description: str, base_seed: int = 0) -> Path:
    """Write designed conditions as a DOE TOML file (atomically); see :func:`doe_document`."""
    path = Path(path)
    text = tomli_w.dumps(doe_document(conditions, path.stem, description, base_seed))

    def write(tmp: str) -> None:
        Path(tmp).write_text(text)

    atomic_write(path, write)
    return path


def run_sheet(conditions: pd.DataFrame, seed: int = 0) -> pd.DataFrame:
    """One row per drop in a seeded random order, blocked by lever and drop mass.

    Changing a lever or a drop mass takes time, so the drops of one fixture stay together
    (a block); the order of the blocks and of the drops within each is random (seeded), so that
    drift of the rig over the day does not line up with height or preload.
    """
    rng = np.random.default_rng(seed)
    c = conditions
    blocks = list(c.groupby(["inertia_kgm2", "drop_mass_kg"], sort=True))
    rows = []
    for b, (_, g) in enumerate([blocks[i] for i in rng.permutation(len(blocks))], start=1):
        drops = [(r, k) for r in g.itertuples(index=False) for k in range(int(r.repeats))]
        for i in rng.permutation(len(drops)):
            r, k = drops[i]
            rows.append({"block": b, "case": r.case, "inertia_kgm2": r.inertia_kgm2, "drop_mass_kg": r.drop_mass_kg,
                         "drop_height_m": r.drop_height_m, "preload_nm": r.preload_nm, "repeat": k + 1,
                         "predicted_amplitude_deg": round(float(r.amplitude_deg), 4),
                         "predicted_frequency_hz": round(float(r.frequency_hz), 3), "operator_notes": ""})
    sheet = pd.DataFrame(rows)
    sheet.insert(0, "run", np.arange(1, len(sheet) + 1))
    return sheet[SHEET_COLUMNS]


def condition_records(table: pd.DataFrame) -> list[dict[str, Any]]:
    """Designed conditions as JSON-ready rows (the printed columns, inertia and warnings; NaN as None)."""
    cols = [*TABLE_COLUMNS, "inertia_kgm2", "warnings"]
    return [{k: (None if isinstance(v, float) and not math.isfinite(v) else _plain(v)) for k, v in r.items()}
            for r in table[cols].to_dict(orient="records")]


def _plain(value: Any) -> Any:
    return value.item() if hasattr(value, "item") else value


def wide_floats():
    """A pandas option context: wide lines, four significant digits."""
    return pd.option_context("display.width", 200, "display.float_format", "{:.4g}".format)


def condition_table(table: pd.DataFrame) -> str:
    """The printed columns of designed conditions as fixed-width text."""
    with wide_floats():
        return table[TABLE_COLUMNS].to_string(index=False)


def check_plan_paths(out: str | Path, sheet: str | Path | None = None) -> None:
    """A one-line error unless ``out`` names a TOML file and ``sheet`` (if given) a table format."""
    from droptower.errors import DroptowerError
    from droptower.io.tables import check_table_path

    if Path(out).suffix.lower() != ".toml":
        raise DroptowerError("the test plan is a TOML file: give a name ending in .toml", file=out, where="out")
    if sheet:
        check_table_path(sheet, "sheet")


def write_plan(design: Any, out: str | Path, description: str, sheet: str | Path | None = None,
               seed: int = 0) -> Path:
    """Write a design's plan TOML (``.toml``) and, if given, its run sheet; record both in the design."""
    from droptower.io.tables import write_table

    check_plan_paths(out, sheet)
    plan_file = write_doe(design.conditions, out, description, base_seed=seed)
    if sheet:
        write_table(run_sheet(design.conditions, seed), sheet, "sheet")
    design.plan_file, design.sheet_file = str(plan_file), (str(sheet) if sheet else None)
    return plan_file
