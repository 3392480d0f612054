"""How many repeats reach a target uncertainty of stiffness and damping ratio.

The scatter of one test's stiffness c and damping ratio d comes from the rig's sensor noise
(the logs carry it) through the decay fit: the extractor gives each value a standard
uncertainty. A pilot campaign of one virtual test per designed condition runs through the
whole data path (rig -> log -> extraction) and gives that uncertainty per condition; the mean
of n repeats has it divided by sqrt(n), so n = ceil((u_1 / u_target)^2) for the worst
condition and the worse of c and d.
"""
from __future__ import annotations

import math
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

from droptower.campaign import run_campaign
from droptower.design.choose import Design
from droptower.design.outputs import write_doe

#: At most this many repeats per condition are proposed (beyond it, the rig's own
#: repeatability, not the noise, limits what averaging gains).
MAX_REPEATS = 50


def pilot_uncertainty(design: Design, rig: str | Path, coupling: str | Path) -> pd.DataFrame:
    """One virtual test per designed condition through the data path: per condition the
    relative standard uncertainty of one test's stiffness and damping ratio (fractions)."""
    with tempfile.TemporaryDirectory(prefix="droptower-pilot-") as tmp:
        doe = write_doe(design.conditions.assign(repeats=1), Path(tmp) / "pilot.toml", "pilot: one test per condition")
        results = run_campaign(Path(tmp) / "campaign", rig, coupling, doe, workers=1, progress=False).results
    return pd.DataFrame({
        "inertia_kgm2": results["inertia_kgm2"], "drop_mass_kg": results["drop_mass_kg"],
        "drop_height_m": results["drop_height_m"], "preload_nm": results["preload_nm"],
        "stiffness_relative_std": results["stiffness_nm_per_rad_std"] / results["stiffness_nm_per_rad"],
        "damping_ratio_relative_std": results["damping_ratio_std"] / results["damping_ratio"],
    })


def repeats_for(relative_std: pd.DataFrame, uncertainty_pct: float) -> int:
    """Repeats that bring the worst condition's mean within ``uncertainty_pct`` (standard
    uncertainty, % of the value) for both stiffness and damping ratio."""
    worst = float(np.nanmax(relative_std[["stiffness_relative_std", "damping_ratio_relative_std"]].to_numpy()))
    if not math.isfinite(worst):
        return 1
    return int(min(MAX_REPEATS, max(1, math.ceil((worst / (uncertainty_pct / 100.0)) ** 2))))
