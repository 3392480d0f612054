"""Design a drop-tower campaign from a target region: which levers, masses and heights.

Every drop the rig can make is predicted first (the planner's batched free decay on the
nonlinear coupling: impact law, preload, double-impact check, sensor ranges, twist limit,
samples per period; :func:`droptower.rig.predictions.plan`). A lever fixture traces one curve in the
(amplitude, frequency) plane as the drop height rises (the coupling softens, so the frequency
falls), and the drop mass only moves the heights along it. The campaign then takes:

- the fewest levers whose curves' hull covers the reachable part of the target (at least three
  where the target spans frequencies and the rig has them, so that the map's frequency terms
  are determined by more than two levels);
- on each, heights evenly spaced in log amplitude (at most :data:`LEVEL_STEP_DECADES` apart,
  reaching a little beyond the target's edges where the rig can), with the lighter drop mass
  wherever it reaches the amplitude without a limit being hit;
- single drops added where the hull still misses part of the reachable target.
"""
from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from droptower.design.coverage import Target, covered_fraction, in_hull, plane
from droptower.errors import DroptowerError, expects
from droptower.rheology import Coupling
from droptower.rig.config import RigConfig
from droptower.rig.predictions import plan, record_length_s

#: Candidate drop heights per lever and mass, log-spaced over the rig's height range.
CANDIDATE_HEIGHTS = 16
#: Largest spacing of the amplitude levels on one lever (decades; 0.2 = a factor 1.58).
LEVEL_STEP_DECADES = 0.2
#: How far beyond the target's amplitude edges the outer levels reach where the rig can
#: (decades): the realised tests scatter about the prediction, the hull must still hold the edge.
EDGE_MARGIN_DECADES = 0.02
#: A designed height is rounded to this (m): what a lab sets.
HEIGHT_RESOLUTION_M = 0.001
#: Record length after the impact used for the 3/4-period check (s), as ``droptower plan``.
RECORD_S = 0.25
#: Least clearance between the falling mass and the lever tip after the impact (mm): a drop that
#: misses a second impact by less would hit in a real rig whose drops scatter.
MIN_CLEARANCE_MM = 1.0
#: Columns that identify one designed condition.
CONDITION_KEYS = ["case", "inertia_kgm2", "drop_mass_kg", "drop_height_m", "preload_nm"]


@dataclass
class Design:
    """A designed campaign.

    conditions: the planner's prediction for every designed condition (one row per lever,
    mass, height and preload) with ``repeats``; candidates: every drop considered (all levers,
    masses, candidate heights, first preload) with ``feasible`` and ``problems``;
    covered_fraction: of the target grid, inside the hull of the designed conditions;
    reachable_fraction: inside the hull of every feasible drop of the rig; unreachable: one
    sentence per part of the target the rig cannot reach, and why; limits_hit: what
    constrained the design (the test budget, a limit of the rig).
    """

    target: Target
    conditions: pd.DataFrame
    candidates: pd.DataFrame
    covered_fraction: float
    reachable_fraction: float
    unreachable: list[str] = field(default_factory=list)
    limits_hit: list[str] = field(default_factory=list)
    repeats: int = 1
    rig_name: str = ""
    coupling_name: str = ""
    plan_file: str | None = None
    sheet_file: str | None = None

    @property
    def n_conditions(self) -> int:
        return len(self.conditions)

    def write(self, out: str | Path, sheet: str | Path | None = None, seed: int = 0) -> Path:
        """Write the plan TOML ``out`` (what :func:`~droptower.campaign.run_campaign` runs as its
        ``doe``) and, if given, the lab's run ``sheet`` (a table: seeded random order blocked by
        lever and mass); returns the plan's path (also in :attr:`plan_file`)."""
        from droptower.design.outputs import coverage_description, write_plan

        return write_plan(self, out, coverage_description(self), sheet, seed)

    def to_frame(self) -> pd.DataFrame:
        """The designed conditions, one row per lever, mass, height and preload (with ``repeats``
        and the planner's prediction)."""
        return self.conditions.copy()

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: tests, conditions, coverage, what the rig cannot reach, limits, files."""
        from droptower.design.outputs import condition_records

        return {"tests": self.n_tests, "conditions": condition_records(self.conditions),
                "target_covered_fraction": self.covered_fraction, "reachable_fraction": self.reachable_fraction,
                "unreachable": list(self.unreachable), "double_impacts_predicted": self.double_impacts_predicted,
                "limits_hit": list(self.limits_hit), "repeats": self.repeats, "plan_file": self.plan_file,
                "sheet_file": self.sheet_file}

    def summary(self) -> str:
        """The design in a few lines: tests, coverage, the condition table, what is out of reach."""
        from droptower.design.outputs import condition_table

        lines = [f"{self.n_conditions} conditions x {self.repeats} repeats = {self.n_tests} drops on rig "
                 f"{self.rig_name} with {self.coupling_name}; {100 * self.covered_fraction:.0f} % of the target "
                 f"covered ({100 * self.reachable_fraction:.0f} % reachable with this rig)", condition_table(self.conditions)]
        lines += [f"unreachable: {line}" for line in self.unreachable]
        lines += [f"limit: {line}" for line in self.limits_hit]
        lines.append(f"{self.double_impacts_predicted} double impact(s) predicted")
        return "\n".join(lines)

    def __repr__(self) -> str:
        return (f"<Design: {self.n_conditions} conditions x {self.repeats} repeats = {self.n_tests} drops, "
                f"{100 * self.covered_fraction:.0f} % of the target covered>")

    def _repr_html_(self) -> str:
        from droptower.design.outputs import TABLE_COLUMNS

        return f"<p>{repr(self).strip('<>')}</p>" + self.conditions[TABLE_COLUMNS].to_html(index=False)

    @property
    def n_tests(self) -> int:
        return int(self.conditions["repeats"].sum())

    @property
    def double_impacts_predicted(self) -> int:
        return int(self.conditions["double_impact"].sum())


def lever_name(rig: RigConfig, inertia_kgm2: float) -> str:
    """``lever 1 (0.1557 kg*m^2)``: the fixture's place in the rig file, lightest first."""
    order = sorted(rig.inertias_kgm2)
    return f"lever {order.index(inertia_kgm2) + 1} ({inertia_kgm2:g} kg*m^2)"


@expects(rig="droptower.rig.config.RigConfig", coupling="droptower.rheology.coupling.Coupling")
def predict_candidates(rig: RigConfig, coupling: Coupling, preloads_nm: tuple[float, ...],
                       n_heights: int = CANDIDATE_HEIGHTS) -> pd.DataFrame:
    """Every lever x mass x log-spaced height, predicted at every preload in one batch.

    One row per (lever, mass, height) with the first preload's prediction, ``feasible`` (no
    warning at any preload) and ``problems`` (the warnings, with the preload they came at).
    """
    heights = np.geomspace(*rig.drop_height_range_m, n_heights)
    rows = [(lever_name(rig, j), j, m, h, p, 1) for j in sorted(rig.inertias_kgm2)
            for m in sorted(rig.drop_masses_kg) for h in heights for p in preloads_nm]
    cond = pd.DataFrame(rows, columns=[*CONDITION_KEYS, "repeats"])
    pred = plan(rig, coupling, cond, RECORD_S)
    pred["fixture"] = pred.groupby(["inertia_kgm2", "drop_mass_kg", "drop_height_m"], sort=False).ngroup()
    problems = pred.groupby("fixture", sort=False).apply(
        lambda g: [f"{w} (preload {p:g} N*m)" if len(preloads_nm) > 1 else w
                   for p, ws in zip(g["preload_nm"], with_margin(g)) for w in ws], include_groups=False)
    first = pred[pred["preload_nm"] == preloads_nm[0]].set_index("fixture")
    first["problems"] = problems
    first["feasible"] = first["problems"].map(len) == 0
    return first.reset_index(drop=True)


def with_margin(pred: pd.DataFrame) -> list[list[str]]:
    """The planner's warnings plus a double-impact clearance below :data:`MIN_CLEARANCE_MM`."""
    return [[*w] + ([f"double-impact clearance {c:.2g} mm < {MIN_CLEARANCE_MM:g} mm"]
                    if not d and c < MIN_CLEARANCE_MM else [])
            for w, d, c in zip(pred["warnings"], pred["double_impact"], pred["min_clearance_mm"])]


def _levels(target: Target, step: float) -> np.ndarray:
    lo = math.log10(target.amplitude_deg[0]) - EDGE_MARGIN_DECADES
    hi = math.log10(target.amplitude_deg[1]) + EDGE_MARGIN_DECADES
    return np.linspace(lo, hi, max(2, math.ceil((hi - lo) / step) + 1)) if hi > lo else np.array([lo])


def _lever_drops(feasible: pd.DataFrame, levels: np.ndarray) -> list[tuple[float, float, float, float, float]]:
    """(inertia, mass, height, log10 amplitude, frequency) per amplitude level on one lever:
    the mass whose run of feasible heights reaches the level (the lighter one where both do;
    levels beyond the lever's reach move to its ends), height and frequency by interpolation
    in log amplitude between the candidates."""
    runs = []
    for mass, g in feasible.groupby("drop_mass_kg"):  # lighter mass first
        g = g.sort_values("amplitude_deg")
        runs.append((mass, np.log10(g["amplitude_deg"].to_numpy()), np.log10(g["drop_height_m"].to_numpy()),
                     g["frequency_hz"].to_numpy()))
    inertia = float(feasible["inertia_kgm2"].iloc[0])
    drops = {}
    for level in levels:
        best = None
        for mass, la, lh, f in runs:
            a = min(max(level, la[0]), la[-1])
            if best is None or abs(a - level) < best[0] - 1e-12:
                best = (abs(a - level), mass, a, float(np.interp(a, la, lh)), float(np.interp(a, la, f)))
        _, mass, a, log_h, freq = best
        drops[round(a, 6)] = (inertia, float(mass), 10.0 ** log_h, a, freq)
    return list(drops.values())


def contiguous_feasible(cands: pd.DataFrame) -> pd.DataFrame:
    """Per lever and mass, the longest run of consecutive feasible heights (interpolating
    across an infeasible height would place a drop where a limit is hit)."""
    keep = []
    for _, g in cands.sort_values("drop_height_m", kind="stable").groupby(["inertia_kgm2", "drop_mass_kg"], sort=False):
        ok = g["feasible"].to_numpy()
        best, start = (0, 0), None
        for i, v in enumerate([*ok, False]):
            if v and start is None:
                start = i
            elif not v and start is not None:
                best = max(best, (i - start, start))
                start = None
        n, s = best
        if n >= 2:
            keep.append(g.iloc[s:s + n])
    return pd.concat(keep) if keep else cands.iloc[:0]


def _round_height(rig: RigConfig, h: float) -> float:
    lo, hi = rig.drop_height_range_m
    return float(min(max(round(round(h / HEIGHT_RESOLUTION_M) * HEIGHT_RESOLUTION_M, 6), lo), hi))


def _choose(rig: RigConfig, feasible: pd.DataFrame, target: Target, step: float) -> list[tuple[float, float, float]]:
    """The designed drops (inertia, mass, height) before the final prediction."""
    grid = target.grid()
    reach = grid[in_hull(plane(feasible["amplitude_deg"], feasible["frequency_hz"]), grid)]
    levels = _levels(target, step)
    per_lever = {j: _lever_drops(g, levels) for j, g in feasible.groupby("inertia_kgm2")}

    def coverage(drops) -> float:
        return float(np.mean(in_hull(np.array([d[3:] for d in drops]), reach))) if len(reach) else 0.0

    best = None
    for k in range(1, len(per_lever) + 1):
        for subset in itertools.combinations(sorted(per_lever), k):
            drops = [d for j in subset for d in per_lever[j]]
            key = (round(coverage(drops), 3), -len(drops))
            if best is None or key > best[0]:
                best = (key, subset)
    subset = list(best[1])
    # a frequency span wants at least three frequency levels for the map's frequency terms:
    # add the levers whose curves cross the target band, nearest to its middle first
    f_lo, f_hi = target.frequency_hz
    median_f = feasible.groupby("inertia_kgm2")["frequency_hz"].median()
    in_band = [j for j, g in feasible.groupby("inertia_kgm2") if g["frequency_hz"].between(f_lo, f_hi).any()]
    for j in sorted(set(in_band) - set(subset), key=lambda j: abs(median_f[j] - 0.5 * (f_lo + f_hi))):
        if f_hi == f_lo or len(subset) >= 3:
            break
        subset.append(j)
    drops = [d for j in sorted(subset) for d in per_lever[j]]
    # single candidate drops where the hull still misses reachable target points
    cand = [(j, m, h, np.log10(a), f) for j, m, h, a, f in zip(
        feasible["inertia_kgm2"], feasible["drop_mass_kg"], feasible["drop_height_m"],
        feasible["amplitude_deg"], feasible["frequency_hz"])]
    while len(reach):
        pts = np.array([d[3:] for d in drops])
        missing = reach[~in_hull(pts, reach)]
        if not len(missing):
            break
        gains = [int(np.sum(in_hull(np.vstack([pts, c[3:]]), missing))) for c in cand]
        if max(gains) == 0:
            break
        drops.append(cand[int(np.argmax(gains))])
    return [(j, m, _round_height(rig, h)) for j, m, h, _, _ in drops]


def _unreachable(target: Target, all_pts: np.ndarray, feasible: pd.DataFrame, rig: RigConfig) -> list[str]:
    """Sentences for the parts of the target the rig cannot reach, per amplitude band."""
    grid = target.grid()
    n = int(round(math.sqrt(len(grid))))
    inside = in_hull(all_pts, grid).reshape(n, n)
    amps = 10 ** grid[:, 0].reshape(n, n)[:, 0]
    freqs = grid[:, 1].reshape(n, n)[0]
    out = []
    if not inside.any():
        return out
    f_lo, f_hi = target.frequency_hz
    by_lever = feasible.groupby("inertia_kgm2")
    high = [j for j, _ in sorted(by_lever, key=lambda t: -t[1]["frequency_hz"].max())][0]
    low = [j for j, _ in sorted(by_lever, key=lambda t: t[1]["frequency_hz"].min())][0]
    for side, bound, lever, word in (("highest", f_hi, high, "lightest"), ("lowest", f_lo, low, "heaviest")):
        bands = []
        for i, a in enumerate(amps):
            row = inside[i]
            reach_f = freqs[row]
            if not len(reach_f):
                bands.append((a, None))
                continue
            edge = reach_f.max() if side == "highest" else reach_f.min()
            missing = edge < bound - 1e-9 if side == "highest" else edge > bound + 1e-9
            bands.append((a, edge if missing else False))
        runs = [list(g) for k, g in itertools.groupby(bands, key=lambda b: b[1] is False) if not k]
        for run in runs:
            a0, a1 = run[0][0], run[-1][0]
            edges = [e for _, e in run if e is not None]
            amp_text = f"{a0:.2g}-{a1:.2g} deg" if a1 > a0 else f"{a0:.2g} deg"
            if not edges:
                out.append(f"at {amp_text} no drop of the rig lands in {f_lo:g}-{f_hi:g} Hz")
                continue
            worst = max(edges) if side == "highest" else min(edges)
            out.append(f"at {amp_text} the {side} frequency reachable is {worst:.3g} Hz: the {word} lever, "
                       f"{lever_name(rig, lever)}")
    # amplitudes the rig cannot reach at all within its heights and limits
    reach_a = 10 ** all_pts[:, 0]
    if target.amplitude_deg[1] > reach_a.max():
        out.append(f"above {reach_a.max():.3g} deg no drop is possible without hitting a limit of rig {rig.name} "
                   "(double impact, twist, sensor ranges or drop height)")
    if target.amplitude_deg[0] < reach_a.min():
        out.append(f"below {reach_a.min():.3g} deg no drop is possible: the lowest drop height "
                   f"{rig.drop_height_range_m[0]:g} m gives more")
    return out


@expects(rig="droptower.rig.config.RigConfig", coupling="droptower.rheology.coupling.Coupling", target="droptower.design.coverage.Target")
def design_campaign(rig: RigConfig, coupling: Coupling, target: Target, *, repeats: int = 3,
                    max_tests: int | None = None, candidates: pd.DataFrame | None = None) -> Design:
    """Design the conditions that cover ``target`` on ``rig`` with ``coupling``.

    repeats: repeats per condition; max_tests: the budget (repeats, then the amplitude
    spacing give way to it); candidates: :func:`predict_candidates` already computed.
    """
    cands = predict_candidates(rig, coupling, target.preloads_nm) if candidates is None else candidates
    feasible = contiguous_feasible(cands)
    if feasible.empty:
        raise DroptowerError(f"no drop of rig {rig.name} with coupling {coupling.name} is possible without hitting a "
                             "limit (double impact, twist, sensor ranges)")
    all_pts = plane(feasible["amplitude_deg"], feasible["frequency_hz"])
    reachable = covered_fraction(all_pts, target)
    if reachable == 0.0:
        raise DroptowerError(
            f"the target {target.amplitude_deg[0]:g}-{target.amplitude_deg[1]:g} deg x {target.frequency_hz[0]:g}-"
            f"{target.frequency_hz[1]:g} Hz lies outside what rig {rig.name} reaches with coupling {coupling.name}: "
            f"{feasible['amplitude_deg'].min():.3g}-{feasible['amplitude_deg'].max():.3g} deg at "
            f"{feasible['frequency_hz'].min():.3g}-{feasible['frequency_hz'].max():.3g} Hz",
            where="amplitude_deg/frequency_hz")
    limits: list[str] = []
    n_pre = len(target.preloads_nm)
    step = LEVEL_STEP_DECADES
    while True:
        drops = _choose(rig, feasible, target, step)
        n_cond = len(set(drops)) * n_pre
        if max_tests is None or n_cond * repeats <= max_tests:
            break
        if repeats > 1:
            new = max(1, max_tests // n_cond)
            limits.append(f"`max_tests={max_tests}`: {new} repeat(s) per condition instead of {repeats}")
            repeats = new
            continue
        if step >= 1.0:
            raise DroptowerError(f"{n_cond} conditions (the fewest that span the target, each at {n_pre} preload(s)) "
                                 f"exceed `max_tests={max_tests}`", where="max_tests")
        step *= 1.25
        limits.append(f"`max_tests={max_tests}`: amplitude levels {step:.2g} decades apart")
    rows = [(lever_name(rig, j), j, m, h, p, repeats) for j, m, h in sorted(set(drops)) for p in target.preloads_nm]
    cond = pd.DataFrame(rows, columns=[*CONDITION_KEYS, "repeats"])
    # predicted as the campaign will record and extract them (its record length for this plan)
    pred = plan(rig, coupling, cond, record_length_s(plan(rig, coupling, cond, RECORD_S)["first_period_s"]))
    pred["warnings"] = with_margin(pred)
    for r in pred[pred["warnings"].map(len) > 0].itertuples():
        limits.append(f"{r.case}, {r.drop_mass_kg:g} kg, {r.drop_height_m:g} m: " + "; ".join(r.warnings))
    pts = plane(pred["amplitude_deg"], pred["frequency_hz"])
    return Design(target=target, conditions=pred, candidates=cands,
                  covered_fraction=covered_fraction(pts, target), reachable_fraction=reachable,
                  unreachable=_unreachable(target, all_pts, feasible, rig), limits_hit=limits, repeats=repeats)
