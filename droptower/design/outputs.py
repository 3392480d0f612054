"""What a designed campaign hands to the lab: a test-plan TOML and a randomised run sheet."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import tomli_w

from droptower.design.choose import Design
from droptower.io.droptower_log import atomic_write

#: Columns of the lab's run sheet, in order.
SHEET_COLUMNS = ["run", "block", "case", "inertia_kgm2", "drop_mass_kg", "drop_height_m", "preload_nm", "repeat",
                 "predicted_amplitude_deg", "predicted_frequency_hz", "operator_notes"]


def doe_document(design: Design, name: str, base_seed: int = 0) -> dict[str, Any]:
    """The test plan as the DOE TOML format holds it (``campaign --doe`` runs it as it is):
    one group per lever and drop mass, each with its own heights; preloads and repeats for all."""
    t = design.target
    groups = []
    for (case, j, m), g in design.conditions.groupby(["case", "inertia_kgm2", "drop_mass_kg"], sort=True):
        groups.append({"name": f"{case}, {m:g} kg", "inertia_kgm2": float(j), "drop_mass_kg": float(m),
                       "heights_m": sorted({float(h) for h in g["drop_height_m"]})})
    all_heights = sorted({h for g in groups for h in g["heights_m"]})
    return {
        "name": name,
        "description": (f"designed by droptower design for {t.amplitude_deg[0]:g}-{t.amplitude_deg[1]:g} deg x "
                        f"{t.frequency_hz[0]:g}-{t.frequency_hz[1]:g} Hz: {design.n_conditions} conditions, "
                        f"{design.n_tests} tests, {100 * design.covered_fraction:.0f} % of the target covered"),
        "source": "droptower design",
        "base_seed": int(base_seed),
        "repeats": int(design.repeats),
        "heights_m": all_heights,
        "preloads_nm": [float(p) for p in t.preloads_nm],
        "group": groups,
    }


def write_doe(design: Design, path: str | Path, base_seed: int = 0) -> Path:
    """Write the designed plan as a DOE TOML file (atomically)."""
    path = Path(path)
    text = tomli_w.dumps(doe_document(design, path.stem, base_seed))

    def write(tmp: str) -> None:
        Path(tmp).write_text(text)

    atomic_write(path, write)
    return path


def run_sheet(design: Design, seed: int = 0) -> pd.DataFrame:
    """One row per drop in a seeded random order, blocked by lever and drop mass.

    Changing a lever or a drop mass takes time, so the drops of one fixture stay together
    (a block); the order of the blocks and of the drops within each is random (seeded), so that
    drift of the rig over the day does not line up with height or preload.
    """
    rng = np.random.default_rng(seed)
    c = design.conditions
    blocks = list(c.groupby(["inertia_kgm2", "drop_mass_kg"], sort=True))
    rows = []
    for b, ((j, m), g) in enumerate([blocks[i] for i in rng.permutation(len(blocks))], start=1):
        drops = [(r, k) for r in g.itertuples(index=False) for k in range(int(r.repeats))]
        for i in rng.permutation(len(drops)):
            r, k = drops[i]
            rows.append({"block": b, "case": r.case, "inertia_kgm2": r.inertia_kgm2, "drop_mass_kg": r.drop_mass_kg,
                         "drop_height_m": r.drop_height_m, "preload_nm": r.preload_nm, "repeat": k + 1,
                         "predicted_amplitude_deg": round(float(r.amplitude_ref_deg), 4),
                         "predicted_frequency_hz": round(float(r.frequency_hz), 3), "operator_notes": ""})
    sheet = pd.DataFrame(rows)
    sheet.insert(0, "run", np.arange(1, len(sheet) + 1))
    return sheet[SHEET_COLUMNS]
