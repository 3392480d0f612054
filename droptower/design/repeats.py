"""How many repeats reach a target uncertainty of stiffness and damping ratio.

The scatter of one test's stiffness c and damping ratio d comes from the rig's sensor noise
(the logs carry it) through the decay fit: the extractor gives each value a standard
uncertainty. A pilot campaign of one virtual test per designed condition runs through the
whole data path (rig -> log -> extraction) and gives that uncertainty per condition; the mean
of n repeats has it divided by sqrt(n), so n = ceil((u_1 / u_target)^2) for the worst
condition and the worse of c and d.

The rig's inputs do not average out (GUM 5.2; docs/guide/uncertainty.md): one lever inertia J
serves every repeat of a fixture, so its relative uncertainty u_J/J stays in the stiffness of
the mean however many drops are made (c = J(ω² + δ²); the damping ratio carries none of it).
With the inputs' share u_in the mean's uncertainty is √(u_1²/n + u_in²), so
n = ceil(u_1² / (u_target² − u_in²)); where u_in ≥ u_target no number of repeats reaches the
target and :func:`repeats_advice` says which input stands in the way.
"""
from __future__ import annotations

import math
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

from dataclasses import dataclass

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


def repeats_for(relative_std: pd.DataFrame, uncertainty_pct: float, uncertainty: object = None) -> int:
    """Repeats that bring the worst condition's mean within ``uncertainty_pct`` (standard
    uncertainty, % of the value) for both stiffness and damping ratio; with ``uncertainty`` (a
    :class:`~droptower.rig.uncertainty.RigUncertainty`) the inputs' share counted
    (:func:`repeats_advice`)."""
    return repeats_advice(relative_std, uncertainty_pct, uncertainty).repeats


@dataclass(frozen=True)
class RepeatsAdvice:
    """How many repeats per condition (``repeats``), whether they reach the target
    (``reachable``), and ``limit``: why not (the input whose share alone exceeds the target), "" if they do."""

    repeats: int
    reachable: bool
    limit: str = ""


def input_share(relative_std: pd.DataFrame, uncertainty: object = None) -> pd.DataFrame:
    """Per condition (the rows of ``relative_std``, with ``inertia_kgm2``) the relative standard
    uncertainty the rig's inputs give the mean stiffness and damping ratio (fractions; repeats do
    not reduce it) and the input behind it: u_J/J of the condition's fixture for the stiffness,
    none for the damping ratio (``stiffness_input``: ``inertia_kgm2@J``, "" where not given)."""
    n = len(relative_std)
    rel = np.zeros(n)
    name = [""] * n
    if uncertainty is not None and "inertia_kgm2" in relative_std.columns:
        for i, j in enumerate(relative_std["inertia_kgm2"].to_numpy(float)):
            entry = uncertainty.inertia(j)
            if entry is not None:
                rel[i], name[i] = entry.standard / j, f"inertia_kgm2@{j:g}"
    return pd.DataFrame({"stiffness_input_relative_u": rel, "damping_ratio_input_relative_u": np.zeros(n),
                         "stiffness_input": name}, index=relative_std.index)


def repeats_advice(relative_std: pd.DataFrame, uncertainty_pct: float, uncertainty: object = None) -> RepeatsAdvice:
    """The repeats that bring every condition's mean within ``uncertainty_pct`` (% of the value,
    standard) for stiffness and damping ratio: u_mean² = u_1²/n + u_in² (module docstring).

    Where an input's share u_in alone reaches the target, no n does: ``reachable`` is False,
    ``limit`` names the input, and ``repeats`` is where the fit's share falls below the input's
    (n = ceil(u_1²/u_in²), more gains little), at most :data:`MAX_REPEATS`.
    """
    target = uncertainty_pct / 100.0
    shares = input_share(relative_std, uncertainty)
    need, limits = 1, []
    for q in ("stiffness", "damping_ratio"):
        u1 = relative_std[f"{q}_relative_std"].to_numpy(float)
        u_in = shares[f"{q}_input_relative_u"].to_numpy(float)
        for i in np.flatnonzero(np.isfinite(u1)):
            if u_in[i] >= target:
                limits.append((u_in[i], q, shares["stiffness_input"].iloc[i]))
                n = math.ceil((u1[i] / u_in[i]) ** 2) if u_in[i] > 0 else 1
            else:
                n = math.ceil(u1[i] ** 2 / (target ** 2 - u_in[i] ** 2))
            need = max(need, n)
    repeats = int(min(MAX_REPEATS, max(1, need)))
    if not limits:
        return RepeatsAdvice(repeats, True)
    u_in, q, name = max(limits)
    return RepeatsAdvice(repeats, False,
                         f"{name} alone gives the mean {q.replace('_', ' ')} {100 * u_in:.3g} % (standard), at or above "
                         f"the target {uncertainty_pct:g} %: no number of repeats reaches it (one J serves every "
                         f"repeat); a better figure for that input does; {repeats} repeat(s) bring the fit's share "
                         "below it")
