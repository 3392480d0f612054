"""What the planner page computes in the browser from: the planner's predictions on a grid.

The page has no Python: every lever x drop mass x height x preload of the rig is predicted here
(the nonlinear free decay, impact law, double-impact check and limits of
:func:`droptower.rig.predictions.plan`, in batches) on heights log-spaced over the rig's range, and
where linear interpolation in log height misses a direct prediction at an interval's middle
by more than :data:`REFINE_TOLERANCE`, the interval is halved (amplitude and frequency vary
smoothly with height, about as its square root and slowly, except where the coupling's
response jumps: the shipped coupling at 1000 N*m preload on the heaviest lever falls from 31.4
to 28.8 Hz between 0.195 and 0.219 m). The design's candidates (:func:`droptower.design.choose.predict_candidates` and
its runs of feasible heights) are embedded as they are, in the order the design reads them,
so that the page's selection repeats ``droptower design``'s exactly.
"""
from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from droptower.design import choose
from droptower.design.coverage import GRID_POINTS
from droptower.errors import DroptowerError, expects
from droptower.jsonsafe import json_safe
from droptower.rheology import Coupling
from droptower.rig.config import RigConfig
from droptower.rig.predictions import MIN_SAMPLES_PER_PERIOD, plan

#: Heights the grid starts from per lever, mass and preload, log-spaced over the rig's range ...
GRID_HEIGHTS = 41
#: ... then an interval is halved (in log height) wherever linear interpolation misses the direct
#: prediction at its middle by more than this fraction (amplitude or frequency, any lever, mass
#: or preload) ...
REFINE_TOLERANCE = 0.002
#: ... at most this many times: a jump in the coupling's response is only narrowed, never resolved.
REFINE_ROUNDS = 4
#: Predicted quantities the page shows, interpolated in log height (units in their names).
QUANTITIES = ("amplitude_deg", "frequency_hz", "damping_ratio", "peak_torque_nm", "impact_force_peak_n",
              "min_clearance_mm", "max_twist_deg", "samples_per_period", "impact_velocity_m_per_s")


def check_preloads(rig: RigConfig, preloads_nm: tuple[float, ...]) -> None:
    """A one-line error for a preload (N*m) outside the rig's range."""
    lo, hi = rig.preload_range_nm
    for p in preloads_nm:
        if not lo <= p <= hi:
            raise DroptowerError(f"preload {p:g} N*m is outside the range {lo:g}-{hi:g} N*m of rig {rig.name}",
                                 where="preloads_nm")


def _grid(rig: RigConfig, coupling: Coupling, curves: list[tuple[float, float, float]],
          n_heights: int) -> tuple[np.ndarray, pd.DataFrame]:
    """Heights (m, ascending) and the planner's predictions at them for every curve (inertia,
    mass, preload): one row per curve and height, curve-major; refined where interpolation misses."""

    def predict(heights: np.ndarray) -> pd.DataFrame:
        rows = [(choose.lever_name(rig, j), j, m, h, p, 1, c) for c, (j, m, p) in enumerate(curves) for h in heights]
        return plan(rig, coupling, pd.DataFrame(rows, columns=[*choose.CONDITION_KEYS, "repeats", "curve"]),
                    choose.RECORD_S)

    heights = np.geomspace(*rig.drop_height_range_m, n_heights)
    pred = predict(heights)
    check = np.arange(n_heights - 1)  # intervals [heights[i], heights[i + 1]] to check
    for _ in range(REFINE_ROUNDS):
        mids = np.sqrt(heights[check] * heights[check + 1])
        at_mid = predict(mids)
        bad = np.zeros(len(check), bool)
        for q in ("amplitude_deg", "frequency_hz"):
            v = pred[q].to_numpy(float).reshape(len(curves), len(heights))
            guess = 0.5 * (v[:, check] + v[:, check + 1])  # linear in log height at the geometric middle
            direct = at_mid[q].to_numpy(float).reshape(len(curves), len(mids))
            with np.errstate(invalid="ignore", divide="ignore"):
                miss = (np.abs(guess / direct - 1) > REFINE_TOLERANCE) | (np.isnan(guess) != np.isnan(direct))
            bad |= miss.any(axis=0)
        if not bad.any():
            break
        keep = at_mid[np.tile(bad, len(curves))]
        pred = pd.concat([pred, keep]).sort_values(["curve", "drop_height_m"], kind="stable", ignore_index=True)
        heights = np.sort(np.concatenate([heights, mids[bad]]))
        added = np.flatnonzero(np.isin(heights, mids[bad]))
        check = np.unique(np.concatenate([added - 1, added]))
    return heights, pred


@expects(rig="droptower.rig.config.RigConfig", coupling="droptower.rheology.coupling.Coupling")
def planner_data(rig: RigConfig, coupling: Coupling, preloads_nm: tuple[float, ...],
                 n_heights: int = GRID_HEIGHTS) -> dict[str, Any]:
    """The page's data: the rig, the grid of predictions, the design's candidates and settings.

    ``grid[q]`` is flat, index ``((lever * n_masses + mass) * n_preloads + preload) * len(heights_m)
    + height`` (levers and masses ascending, preloads as given); ``grid["ok"]``: no warning of the
    planner and at least :data:`~droptower.design.choose.MIN_CLEARANCE_MM` clearance.
    """
    check_preloads(rig, preloads_nm)
    feasible = choose.contiguous_feasible(choose.predict_candidates(rig, coupling, preloads_nm))
    if feasible.empty:
        raise DroptowerError(f"no drop of rig {rig.name} with coupling {coupling.name} is possible without hitting a "
                             "limit (double impact, twist, sensor ranges)")
    levers, masses = sorted(rig.inertias_kgm2), sorted(rig.drop_masses_kg)
    heights, pred = _grid(rig, coupling, [(j, m, p) for j in levers for m in masses for p in preloads_nm], n_heights)
    grid: dict[str, list] = {q: json_safe(np.asarray(pred[q], float)) for q in QUANTITIES}  # NaN: no oscillation
    grid["double_impact"] = [bool(v) for v in pred["double_impact"]]
    grid["ok"] = [not w for w in choose.with_margin(pred)]
    return {
        "rig": {"name": rig.name, "drop_height_range_m": list(rig.drop_height_range_m),
                "coupling_limit_deg": rig.coupling_limit_deg, "torque_range_nm": rig.sensors.torque.range_nm,
                "impact_force_range_n": rig.sensors.impact_force.range_n},
        "coupling": coupling.name,
        "levers": [{"inertia_kgm2": j, "case": choose.lever_name(rig, j)} for j in levers],
        "masses_kg": masses,
        "preloads_nm": [float(p) for p in preloads_nm],
        "heights_m": heights.tolist(),
        "grid": grid,
        # the design's candidates in its own row order (its greedy step takes the first best)
        "candidates": {
            "inertia_kgm2": feasible["inertia_kgm2"].astype(float).tolist(),
            "drop_mass_kg": feasible["drop_mass_kg"].astype(float).tolist(),
            "log10_height_m": np.log10(feasible["drop_height_m"].to_numpy(float)).tolist(),
            "log10_amplitude_deg": np.log10(feasible["amplitude_deg"].to_numpy(float)).tolist(),
            "frequency_hz": feasible["frequency_hz"].astype(float).tolist(),
        },
        "settings": {"level_step_decades": choose.LEVEL_STEP_DECADES, "edge_margin_decades": choose.EDGE_MARGIN_DECADES,
                     "height_resolution_m": choose.HEIGHT_RESOLUTION_M, "target_grid_points": GRID_POINTS,
                     "min_clearance_mm": choose.MIN_CLEARANCE_MM, "min_samples_per_period": MIN_SAMPLES_PER_PERIOD,
                     "default_repeats": 3},  # as droptower design
    }
