"""Calibrate the reference coupling ``rapp2022_nr60`` on a joint objective.

    python analysis/calibrate_nr60.py [--out calibration_out] [--write-preset] [--work calibration_work]

Model (elements of the core, see rig_configs/couplings/README.md): a spring (the rubber's
equilibrium stiffness), a ``filler_network`` element (an Iwan network of Jenkins elements for
the friction between filler clusters, whose intact fraction breaks down with the strain about a
slowly moving centre and recovers in time: the Payne effect and a rate-independent loss, valid
for any history) and a ``power_law`` branch (a Prony series spread over the decades of the
test band and above: K' rising with frequency at a nearly flat loss factor).

Objective, every figure through the evaluation a lab would use:

- Table 4 (Rapp et al. 2022): the drop tests' stiffness and damping ratio, each row's case
  interpolated at its amplitude (:func:`droptower.compare.reference_map.compare_reference`);
- drop tower vs servo bench without the map: each drop test's decay (c, d) against the
  steady-state sine test at the decay's own amplitude and frequency (storage stiffness K' and
  the drop-tower-equivalent damping ratio, docs/theory.md#damping-measures);
- the loss factor at 1 Hz at least 0.7x that at 30 Hz (1.5 deg) and the third harmonic of the
  torque at most 5 % of the fundamental (1.5 deg, 30 Hz): penalties beyond 0.75x and 4.5 %.

Fast inner loop: the free decay of the lever (inertia J, the impact law's initial rate,
docs/theory.md#impact) on the core at 38.4 kHz after the rig's preload procedure, fitted over its first cycle
with the extractor's own fit (docs/theory.md#extraction); all 30 conditions (3 cases x the 10 drop heights of
Table 2) in one batch. Output space mapping: a reduced campaign through the whole pipeline
(pymunk impact, sensors, logs, extraction) gives per row the ratio pipeline / fast loop, and the
fast loop is re-fitted against the targets so corrected.

Candidates: the same model fitted with different weights (and without the power-law branch)
show the trade-off between the targets; each candidate's figures come from the reduced
pipeline (30 drop tests -> logs -> extraction -> map -> servo sweeps on the virtual bench) and
are written as a table (``nr60_candidates.csv``). The eligible candidate that misses the fewest
targets becomes the preset, ties broken by the smallest summed relative excess over the targets
(a sum alone lets one far-missed target outweigh several others). Everything is written to
the folder ``--out`` (default ``calibration_out``); only ``--write-preset`` writes the chosen
coupling over the repository's preset (never the installed package) and the tables into
analysis/results/. Reproducible: the fit starts from fixed values and is deterministic, the
pipeline's campaign is seeded, and the directions of the parameter space the objective does
not determine are reported (``nr60_undetermined_directions.csv``) and fixed by a rule (a weak
pull towards the start values, ``PRIOR_DECADES``). Table 4 cross-validated by lever case
(calibrate on two cases, predict the third): ``nr60_cross_validation.csv``. ``--frontier`` fits
only the frontier between the decays' damping bias against the bench and the other targets
(``nr60_frontier.csv``, FRONTIER). The acceptance
numbers of the preset come from the full study (``analysis/run_study.py``).
"""
from __future__ import annotations

import argparse
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.optimize import least_squares

from droptower.campaign import run_campaign
from droptower.compare import compare_with_servo, run_sweeps
from droptower.compare.reference_map import compare_reference
from droptower.data import table4_path
from droptower.damped_cosine import fit_decay, start_frequency_and_decay
from droptower.maps import fit_map
from droptower.rates import RIG_SAMPLE_RATE_HZ
from droptower.rheology import Coupling, coupling_to_toml, parse_coupling
from droptower.rig.config import load_rig
from droptower.rig.impact_law import impact_velocities
from droptower.rig.predictions import free_decay
from droptower.rig.preload import pretwist
from droptower.sdof import damping_ratio, drop_tower_equivalent_damping_ratio, stiffness
from droptower.servo.steady import rubber_figures, steady_state
from run_study import real_time_factor

REPOSITORY = Path(__file__).resolve().parents[1]
CASES = {1: (0.1557, 1.0), 2: (0.359, 2.0), 3: (0.5233, 2.0)}   # J kg*m^2, drop mass kg (docs/theory.md#rig)
LEVER_M, RESTITUTION = 0.2, 0.5
HEIGHTS_M = np.array([0.05, 0.2, 0.4, 0.55, 0.7, 1.0, 1.4, 1.8, 3.5, 6.0])  # Table 2
RATE_HZ = RIG_SAMPLE_RATE_HZ
DURATION_S = 0.075
#: the reference coupling's targets (percent RMS, ratios)
TARGETS = {"table4_stiffness_rms_pct": 5.0, "table4_damping_rms_pct": 12.0,
           "servo_inside_stiffness_rms_pct": 6.0, "servo_inside_damping_rms_pct": 7.0,
           "loss_factor_ratio_1hz_30hz_min": 0.7, "storage_rise_pct_per_decade_min": 3.0,
           "third_harmonic_pct_max": 5.0, "real_time_factor_min": 100.0}
TARGETS_COLUMNS = ["table4_stiffness_rms_pct", "table4_damping_rms_pct", "servo_inside_stiffness_rms_pct",
                   "servo_inside_damping_rms_pct", "loss_factor_ratio_1hz_30hz", "storage_rise_pct_per_decade",
                   "third_harmonic_pct", "real_time_factor"]  # printed
POWER_LAW_MIN_HZ, POWER_LAW_MAX_HZ = 0.3, 3000.0   # the matrix branch spread over the test band and above
POWER_LAW_TERMS_PER_DECADE = 1.5                     # loss ripple 0.2 % (PowerLaw), 7 terms: speed
POWER_LAW_REFERENCE_HZ = 30.0
NETWORK_RECOVERY_S, NETWORK_CENTRE_S = 10.0, 5.0     # settings of the filler network (not fitted)
#: K' of filled rubber rises a few to tens of % per decade (1.5 deg, 1-30 Hz): the objective's
#: penalty starts below this, a little above the target of 3 %
RISE_PENALTY_BELOW = 3.5

#: name, lower bound, upper bound, start (SI, torsional); the fit works on log10 of each
PARAMETERS = [
    ("spring_stiffness", 1e3, 3e4, 5500.0),              # N*m/rad, equilibrium
    ("network_stiffness", 1e3, 1e5, 23000.0),            # N*m/rad, the intact filler network
    ("network_critical_angle", 1e-4, 0.2, 4e-3),         # rad, median yield angle of its sliders
    ("network_exponent", 0.2, 2.0, 0.35),                # -
    ("network_breakdown_angle", 1e-3, 1.0, 0.04),        # rad, halves the intact network
    ("matrix_storage_stiffness", 10.0, 2e4, 600.0),      # N*m/rad at 30 Hz
    ("matrix_loss_factor", 0.02, 2.0, 0.9),              # -
]
NAMES = [p[0] for p in PARAMETERS]
#: The rule that fixes the directions the objective does not determine: a weak pull of every
#: log10 parameter towards its start, one decade costing as much as a residual of 1/PRIOR_DECADES
#: (the data residuals are O(1) each, 60-120 of them): where the data decide, it is negligible;
#: where they do not (a flat direction), it picks the point nearest the start, so two runs agree.
PRIOR_DECADES = 30.0
#: a direction is reported as undetermined when its singular value of the data Jacobian is below
#: this fraction of the largest one (a change along it of 1 decade moves the residuals by < 1e-3x
#: what the best-determined direction does)
FLAT_RATIO = 1e-3
#: finite-difference step of the fit (decades): the fast loop's figures change smoothly only on
#: this scale (the decay fit's window and the sliders' discrete yield angles make them ripple
#: below it)
DIFF_STEP = 0.03


def build(values: dict[str, float], matrix: bool = True, min_frequency_hz: float = POWER_LAW_MIN_HZ) -> Coupling:
    """The coupling for one set of parameter values (SI); ``min_frequency_hz`` the matrix branch's lowest decade."""
    v = values
    elements = [
        {"kind": "spring", "name": "equilibrium", "stiffness": v["spring_stiffness"]},
        {"kind": "filler_network", "name": "filler_network", "stiffness": v["network_stiffness"],
         "critical_angle": v["network_critical_angle"], "exponent": v["network_exponent"],
         "breakdown_angle": v["network_breakdown_angle"], "recovery_time": NETWORK_RECOVERY_S,
         "centre_relaxation_time": NETWORK_CENTRE_S},
    ]
    if matrix:
        elements.append({"kind": "power_law", "name": "matrix", "storage_stiffness": v["matrix_storage_stiffness"],
                         "loss_factor": v["matrix_loss_factor"], "reference_frequency": POWER_LAW_REFERENCE_HZ,
                         "min_frequency": min_frequency_hz, "max_frequency": POWER_LAW_MAX_HZ,
                         "terms_per_decade": POWER_LAW_TERMS_PER_DECADE})
    return parse_coupling({
        "name": "rapp2022_nr60",
        "description": "Natural-rubber disc coupling, Shore A 60 (Rapp et al. 2022): equilibrium spring + filler network "
                       "(Iwan friction network whose structure breaks down with the strain and recovers in time: "
                       "Payne effect, rate-independent loss) + power-law matrix branch spread over the test band "
                       "(K' and the loss rising with frequency), calibrated by analysis/calibrate_nr60.py on Table 4 "
                       "with the drop tower vs servo bench weighted lightly",
        "source": "Rapp et al. 2022, Table 4; Iwan (1966) / Masing friction network with Kraus (1984) "
                  "shapes; power-law (fractional) viscoelasticity as a Prony series",
        "element": [{k: (float(x) if isinstance(x, (int, float, np.floating)) else x) for k, x in e.items()}
                    for e in elements]})


# ---------------------------------------------------------------- the fast loop
def decay_properties(t: np.ndarray, angle: np.ndarray, inertia: float) -> tuple[float, float, float, float, float]:
    """(amplitude deg at the window's middle, frequency Hz, stiffness N*m/deg, d_ratio, the
    envelope's amplitude deg at the window's start) of the first complete cycle, fitted like the
    extractor does (docs/theory.md#extraction)."""
    omega0, delta0 = start_frequency_and_decay(t, angle, 0.0)
    window = t <= 2 * np.pi / omega0
    fit = fit_decay(t[window], angle[window], omega0, delta0)
    amp, delta, omega, _ = fit.params
    t_max = t[window][-1]
    return (np.rad2deg(amp * np.exp(-delta * t_max / 2)), omega / (2 * np.pi),
            float(stiffness(inertia, omega, delta)) * np.pi / 180, float(damping_ratio(delta, omega)), np.rad2deg(amp))


def predict(coupling: Coupling) -> pd.DataFrame:
    """The fast loop's points, one per case and Table-2 drop height, in the columns of a
    campaign's results (so the campaign's own comparison code can use them)."""
    inertia = np.repeat([CASES[c][0] for c in CASES], HEIGHTS_M.size)
    mass = np.repeat([CASES[c][1] for c in CASES], HEIGHTS_M.size)
    heights = np.tile(HEIGHTS_M, len(CASES))
    rate0 = impact_velocities(mass, inertia, LEVER_M, heights, RESTITUTION).rate_after_rad_per_s
    rig = load_rig("rapp2022")  # preload procedure as in a campaign (zero preload)
    at_rest = pretwist(coupling, np.zeros(inertia.size), rig.simulation.preload_ramp_s, rig.simulation.preload_hold_s)
    decay = free_decay(coupling, inertia, rate0, at_rest, 1.0 / RATE_HZ, DURATION_S)
    t = decay.time_s[1:]
    props = np.array([decay_properties(t, a[1:], j) for a, j in zip(decay.angle_rad, inertia)])
    return pd.DataFrame({"inertia_kgm2": inertia, "drop_mass_kg": mass, "drop_height_m": heights,
                         "amplitude_deg": props[:, 0], "frequency_hz": props[:, 1],
                         "stiffness_nm_per_deg": props[:, 2], "damping_ratio": props[:, 3],
                         "initial_amplitude_deg": props[:, 4]})


def servo_at(coupling: Coupling, points: pd.DataFrame, cycles: int = 5) -> pd.DataFrame:
    """Steady-state K' (N*m/deg) and the drop-tower-equivalent d at each point's own amplitude
    and frequency (the map-free comparison, docs/theory.md#damping-measures); ``cycles`` run-in and evaluated cycles
    (the objective uses 2: the filler network's loops close in the first cycle)."""
    ss = steady_state(coupling, np.radians(points["amplitude_deg"].to_numpy()), points["frequency_hz"].to_numpy(),
                      cycles=cycles, run_in_cycles=cycles)
    return pd.DataFrame({"servo_stiffness_nm_per_deg": np.radians(ss.storage_stiffness_nm_per_rad),
                         "servo_damping_ratio": drop_tower_equivalent_damping_ratio(ss.loss_factor)})


@dataclass
class Weights:
    """Residual scales (relative deviations): smaller means heavier."""

    table4_stiffness: float = 0.03
    table4_damping: float = 0.06
    servo_stiffness: float | None = 0.03     # None: left out of the objective
    servo_damping: float | None = 0.04
    matrix: bool = True                      # the power-law branch is part of the model
    loss_factor_ratio: float = 0.02          # scale of the penalty on eta(1 Hz) / eta(30 Hz) below ...
    loss_factor_ratio_floor: float = 0.75    # ... this floor (the target is 0.7)


def data_residuals(log_values: np.ndarray, weights: Weights, table: pd.DataFrame,
                   correction: pd.DataFrame | None = None, cases: tuple[int, ...] = tuple(CASES)) -> np.ndarray:
    """Weighted relative deviations (module docstring) over the Table-4 rows and decays of the
    lever ``cases``; ``correction`` (per Table-4 row: pipeline / fast loop for stiffness and
    damping ratio) maps the fast loop onto the pipeline."""
    coupling = build(dict(zip(NAMES, 10 ** log_values)), weights.matrix)
    points = predict(coupling)
    cmp, _ = compare_reference(table, results=points)
    c, d = cmp["campaign_stiffness_nm_per_deg"], cmp["campaign_damping_ratio"]
    if correction is not None:
        c, d = c * correction["stiffness"], d * correction["damping"]
    rows = cmp["case"].isin(cases).to_numpy()
    parts = [((c / cmp["stiffness_nm_per_deg"] - 1) / weights.table4_stiffness)[rows],
             ((d / cmp["damping_ratio"] - 1) / weights.table4_damping)[rows]]
    if weights.servo_stiffness or weights.servo_damping:
        mine = np.isin(points["inertia_kgm2"], [CASES[k][0] for k in cases])
        servo = servo_at(coupling, points[mine], cycles=2)
        own = points[mine].reset_index(drop=True)
        if weights.servo_stiffness:
            parts.append((own["stiffness_nm_per_deg"] / servo["servo_stiffness_nm_per_deg"] - 1) / weights.servo_stiffness)
        if weights.servo_damping:
            parts.append((own["damping_ratio"] / servo["servo_damping_ratio"] - 1) / weights.servo_damping)
    rubber = rubber_figures(coupling)
    parts.append(np.array([max(0.0, weights.loss_factor_ratio_floor - rubber["loss_factor_ratio"]) / weights.loss_factor_ratio,
                           max(0.0, RISE_PENALTY_BELOW - rubber["storage_rise_pct_per_decade"]) / 0.1,
                           max(0.0, rubber["third_harmonic_pct"] - 4.5) / 0.5]))
    return np.concatenate([np.asarray(p, float) for p in parts])


def flat_directions(jacobian: np.ndarray, names: list[str]) -> list[dict[str, float]]:
    """The parameter directions (in log10 of the parameters) the data residuals do not determine:
    right singular vectors of the data Jacobian whose singular value is below FLAT_RATIO of the
    largest, each as {parameter: component} (components below 0.05 left out) and its ratio."""
    _, sv, vt = np.linalg.svd(jacobian, full_matrices=False)
    out = []
    for value, vector in zip(sv, vt):
        if value < FLAT_RATIO * sv[0]:
            vector = vector * np.sign(vector[np.argmax(np.abs(vector))])
            out.append({"singular_value_ratio": float(value / sv[0]),
                        **{n: round(float(c), 3) for n, c in zip(names, vector) if abs(c) >= 0.05}})
    return out


# ---------------------------------------------------------------- the pipeline
PIPELINE_PLAN = """name = "calibration"
description = "Table 2's cases and heights, one repeat, no preload"
base_seed = 2022000
repeats = 1
heights_m = [0.05, 0.2, 0.4, 0.55, 0.7, 1.0, 1.4, 1.8, 3.5, 6.0]
preloads_nm = [0.0]
[[group]]
inertia_kgm2 = 0.1557
drop_mass_kg = 1.0
[[group]]
inertia_kgm2 = 0.359
drop_mass_kg = 2.0
[[group]]
inertia_kgm2 = 0.5233
drop_mass_kg = 2.0
"""


def pipeline_results(coupling: Coupling, folder: Path) -> pd.DataFrame:
    """The reduced plan (Table 2's cases and heights, one repeat, no preload: the preload does
    not change this coupling) through the whole pipeline: campaign -> logs -> extraction."""
    folder.mkdir(parents=True, exist_ok=True)
    coupling_file = folder / "coupling.toml"
    coupling_file.write_text(coupling_to_toml(coupling))
    doe_file = folder / "plan.toml"
    doe_file.write_text(PIPELINE_PLAN)
    return run_campaign(folder / "campaign", coupling=coupling_file, doe=doe_file, progress=False).results


def pipeline_correction(coupling: Coupling, table: pd.DataFrame, folder: Path) -> pd.DataFrame:
    """Per Table-4 row: full pipeline / fast loop, for stiffness and damping ratio."""
    full, _ = compare_reference(table, results=pipeline_results(coupling, folder))
    fast, _ = compare_reference(table, results=predict(coupling))
    return pd.DataFrame({"stiffness": full["campaign_stiffness_nm_per_deg"] / fast["campaign_stiffness_nm_per_deg"],
                         "damping": full["campaign_damping_ratio"] / fast["campaign_damping_ratio"]})


def pipeline_figures(coupling: Coupling, table: pd.DataFrame, folder: Path) -> dict[str, float]:
    """Every figure of the issue through the reduced pipeline: Table 4, the map fitted to the
    30 tests against the servo sweeps (inside the tested hull), the decays against the bench at
    their own points (map-free), the loss-factor ratio, the third harmonic and the speed."""
    results = pipeline_results(coupling, folder)
    _, t4 = compare_reference(table, results=results)
    validation = compare_with_servo(fit_map(results), run_sweeps(coupling, reduced=False))
    inside = validation.summary["inside"]
    servo = servo_at(coupling, results)
    rubber = rubber_figures(coupling)
    dc = results["stiffness_nm_per_deg"].to_numpy() / servo["servo_stiffness_nm_per_deg"].to_numpy() - 1
    dd = results["damping_ratio"].to_numpy() / servo["servo_damping_ratio"].to_numpy() - 1
    rms = lambda x: float(100 * np.sqrt(np.mean(np.square(x))))  # noqa: E731
    return {"table4_stiffness_rms_pct": t4["campaign"]["stiffness_rms_deviation_pct"],
            "table4_damping_rms_pct": t4["campaign"]["damping_rms_deviation_pct"],
            "servo_inside_stiffness_rms_pct": inside["stiffness_rms_deviation_pct"],
            "servo_inside_damping_rms_pct": inside["damping_rms_deviation_pct"],
            "servo_inside_loss_factor_rms_pct": inside["loss_factor_rms_deviation_pct"],
            "servo_inside_points": inside["n_points"],
            "decay_vs_servo_stiffness_rms_pct": rms(dc), "decay_vs_servo_damping_rms_pct": rms(dd),
            "loss_factor_ratio_1hz_30hz": rubber["loss_factor_ratio"],
            "storage_rise_pct_per_decade": rubber["storage_rise_pct_per_decade"],
            "third_harmonic_pct": rubber["third_harmonic_pct"],
            "real_time_factor": real_time_factor(coupling)}


def target_excess(figures: dict[str, float]) -> tuple[int, float]:
    """(number of targets missed, summed relative excess over them): smaller is better. The
    speed is not ranked: every candidate has the same elements (or fewer), and a timing taken
    while the machine does other work says little (benchmarks/bench_core.py measures it)."""
    excess = []
    for key, limit in TARGETS.items():
        if key == "real_time_factor_min":
            continue
        name = key.removesuffix("_min").removesuffix("_max")
        value = figures[name] if name in figures else figures[key]
        over = limit / value - 1 if key.endswith("_min") else value / limit - 1
        excess.append(max(0.0, over))
    return sum(e > 0 for e in excess), float(sum(excess))


# ---------------------------------------------------------------- candidates
@dataclass
class Candidate:
    name: str
    weights: Weights
    eligible: bool = True
    values: dict[str, float] = field(default_factory=dict)
    figures: dict[str, float] = field(default_factory=dict)
    flat: list[dict[str, float]] = field(default_factory=list)


CANDIDATES = [
    Candidate("table4_only", Weights(servo_stiffness=None, servo_damping=None)),
    Candidate("joint", Weights()),
    Candidate("joint_servo_heavy", Weights(servo_stiffness=0.02, servo_damping=0.02)),
    Candidate("joint_table4_heavy", Weights(servo_stiffness=0.03, servo_damping=0.15)),
    # as joint_table4_heavy, the loss-factor ratio held firmly: the filler network re-forms only
    # while held, so its 1 Hz loss no longer gains from a relaxation tail (docs/theory.md#filler-network)
    Candidate("joint_table4_heavy_rubber", Weights(servo_stiffness=0.03, servo_damping=0.15, loss_factor_ratio=0.004)),
    # shown for the trade-off only: without the matrix branch the model has no frequency
    # dependence at all, so it is not eligible as the preset
    Candidate("joint_without_matrix", Weights(matrix=False), eligible=False),
]


def fit(start: dict[str, float], weights: Weights, table: pd.DataFrame, correction: pd.DataFrame | None,
        max_evaluations: int, cases: tuple[int, ...] = tuple(CASES)) -> tuple[dict[str, float], list[dict[str, float]]]:
    """Least squares on the data residuals plus the prior rule (PRIOR_DECADES) from ``start``:
    deterministic (no random start, fixed finite-difference steps), so two runs give the same
    values. Returns the values and the undetermined directions at the solution."""
    names = NAMES if weights.matrix else NAMES[:5]
    # the variables are 1 + log10(value / start value): least_squares takes its finite-difference
    # steps relative to the variable, so each is DIFF_STEP decades (above the fast loop's ripple)
    shift = np.log10([p[3] for p in PARAMETERS if p[0] in names]) - 1.0
    lo = np.log10([p[1] for p in PARAMETERS if p[0] in names]) - shift
    hi = np.log10([p[2] for p in PARAMETERS if p[0] in names]) - shift
    x0 = np.clip(np.log10([start[n] for n in names]) - shift, lo + 1e-9, hi - 1e-9)
    rest = np.log10([start[n] for n in NAMES[len(names):]])

    def res(x):
        data = data_residuals(np.r_[x + shift, rest], weights, table, correction, cases)
        return np.r_[data, (x - 1.0) / PRIOR_DECADES]

    sol = least_squares(res, x0, bounds=(lo, hi), diff_step=DIFF_STEP, max_nfev=max_evaluations, x_scale=1.0)
    print(f"    least squares: {sol.nfev} evaluations, cost {sol.cost:.4g}, {sol.message}", flush=True)
    flat = flat_directions(sol.jac[:-len(names)], names)
    for f in flat:
        print(f"    undetermined by the data (fixed by the prior rule): {f}", flush=True)
    return {**start, **dict(zip(names, 10 ** (sol.x + shift)))}, flat


def calibrate(candidate: Candidate, table: pd.DataFrame, work: Path, rounds: int, max_evaluations: int) -> None:
    """Fit the fast loop, correct it by the pipeline ``rounds`` times, then take the figures."""
    values = {p[0]: p[3] for p in PARAMETERS}
    values, flat = fit(values, candidate.weights, table, None, max_evaluations)
    for k in range(rounds):
        correction = pipeline_correction(build(values, candidate.weights.matrix), table, work / f"round{k}")
        values, flat = fit(values, candidate.weights, table, correction, max_evaluations)
    candidate.values = values
    candidate.flat = flat
    candidate.figures = pipeline_figures(build(values, candidate.weights.matrix), table, work / "final")


def cross_validate(table: pd.DataFrame, weights: Weights, max_evaluations: int) -> pd.DataFrame:
    """Table 4 by lever case, calibrated on the two other cases (the fast loop, whose decays the
    pipeline reads within 0.5 %): per held-out case the RMS deviations of its rows, next to the
    same case's deviations when all three cases are calibrated together."""
    rows = []
    for held_out in CASES:
        train = tuple(k for k in CASES if k != held_out)
        print(f"cross-validation: calibrate on cases {train}, predict case {held_out}", flush=True)
        values, _ = fit({p[0]: p[3] for p in PARAMETERS}, weights, table, None, max_evaluations, train)
        cmp, _ = compare_reference(table, results=predict(build(values, weights.matrix)))
        mine = cmp[cmp["case"] == held_out]
        dc = mine["campaign_stiffness_nm_per_deg"] / mine["stiffness_nm_per_deg"] - 1
        dd = mine["campaign_damping_ratio"] / mine["damping_ratio"] - 1
        rows.append({"held_out_case": held_out, "rows": len(mine),
                     "stiffness_rms_pct": float(100 * np.sqrt(np.mean(dc ** 2))),
                     "stiffness_mean_pct": float(100 * dc.mean()),
                     "damping_rms_pct": float(100 * np.sqrt(np.mean(dd ** 2))),
                     "damping_mean_pct": float(100 * dd.mean()),
                     **{f"param_{k}": v for k, v in values.items()}})
    return pd.DataFrame(rows)


def by_case(coupling: Coupling, table: pd.DataFrame) -> pd.DataFrame:
    """Table-4 deviations of the fast loop per lever case (does the error sort by case?)."""
    cmp, _ = compare_reference(table, results=predict(coupling))
    dc = cmp["campaign_stiffness_nm_per_deg"] / cmp["stiffness_nm_per_deg"] - 1
    dd = cmp["campaign_damping_ratio"] / cmp["damping_ratio"] - 1
    frame = pd.DataFrame({"case": cmp["case"], "dc": 100 * dc, "dd": 100 * dd})
    return frame.groupby("case").agg(stiffness_mean_pct=("dc", "mean"),
                                     stiffness_rms_pct=("dc", lambda v: float(np.sqrt(np.mean(v ** 2)))),
                                     damping_mean_pct=("dd", "mean"),
                                     damping_rms_pct=("dd", lambda v: float(np.sqrt(np.mean(v ** 2))))).reset_index()


# ---------------------------------------------------------------- the frontier
#: Can the decays' damping bias against the bench be kept below 50 % RMS with the loss-factor
#: ratio (>= 0.7) and Table 4's damping (<= 12 %) met? Fits from the shipped preset with the bias
#: weighted more, the ratio's penalty floor lowered towards its target, one from a matrix branch
#: with a low loss factor (a K' rise with less loss), and the matrix band's lower edge moved (no
#: fit): the slow decades' creep mode is the other source of the bias (docs/theory.md#first-cycle).
FRONTIER = [
    ("bench_d_10pct", Weights(servo_damping=0.10, loss_factor_ratio=0.004), {}),
    ("bench_d_10pct_from_matrix_loss_0.35", Weights(servo_damping=0.10, loss_factor_ratio=0.004),
     {"matrix_loss_factor": 0.35, "matrix_storage_stiffness": 1500.0}),
    ("floor_0.705", Weights(servo_damping=0.15, loss_factor_ratio=0.004, loss_factor_ratio_floor=0.705), {}),
    ("floor_0.708_bench_d_12pct_table4_d_5pct", Weights(servo_damping=0.12, table4_damping=0.05, loss_factor_ratio=0.002,
                                                        loss_factor_ratio_floor=0.708), {}),
    ("floor_0.712_bench_d_10pct", Weights(servo_damping=0.10, loss_factor_ratio=0.004, loss_factor_ratio_floor=0.712), {}),
    ("floor_0.705_bench_d_8pct_table4_d_5pct", Weights(servo_damping=0.08, table4_damping=0.05, loss_factor_ratio=0.004,
                                                       loss_factor_ratio_floor=0.705), {}),
]
FRONTIER_BAND_MIN_HZ = [1.0, 3.0, 10.0]
FRONTIER_EVALUATIONS = 40
#: the decays' damping bias against the bench (percent RMS) the preset met before its filler
#: network re-formed only at rest: the bound the frontier asks for together with the targets
BIAS_BOUND_PCT = 50.0


def fast_figures(coupling: Coupling, table: pd.DataFrame) -> dict[str, float]:
    """The fast loop's figures (noise-free; the pipeline reads its decays within 0.5 %): Table 4,
    the decays against the bench at their own points, the rubber-like figures, and whether all
    of the reference coupling's targets and the bias bound (BIAS_BOUND_PCT) are met."""
    points = predict(coupling)
    servo = servo_at(coupling, points)
    dc = points["stiffness_nm_per_deg"] / servo["servo_stiffness_nm_per_deg"] - 1
    dd = points["damping_ratio"] / servo["servo_damping_ratio"] - 1
    _, t4 = compare_reference(table, results=points)
    rubber = rubber_figures(coupling)
    rms = lambda x: float(100 * np.sqrt(np.mean(np.square(x))))  # noqa: E731
    out = {"table4_stiffness_rms_pct": t4["campaign"]["stiffness_rms_deviation_pct"],
           "table4_damping_rms_pct": t4["campaign"]["damping_rms_deviation_pct"],
           "decay_vs_servo_stiffness_rms_pct": rms(dc), "decay_vs_servo_damping_rms_pct": rms(dd),
           "decay_vs_servo_damping_min_pct": float(100 * dd.min()),
           "loss_factor_ratio_1hz_30hz": rubber["loss_factor_ratio"],
           "storage_rise_pct_per_decade": rubber["storage_rise_pct_per_decade"],
           "third_harmonic_pct": rubber["third_harmonic_pct"]}
    out["meets_all"] = bool(out["table4_stiffness_rms_pct"] <= TARGETS["table4_stiffness_rms_pct"]
                            and out["table4_damping_rms_pct"] <= TARGETS["table4_damping_rms_pct"]
                            and out["loss_factor_ratio_1hz_30hz"] >= TARGETS["loss_factor_ratio_1hz_30hz_min"]
                            and out["storage_rise_pct_per_decade"] >= TARGETS["storage_rise_pct_per_decade_min"]
                            and out["third_harmonic_pct"] <= TARGETS["third_harmonic_pct_max"]
                            and out["decay_vs_servo_damping_rms_pct"] <= BIAS_BOUND_PCT)
    return out


def frontier(table: pd.DataFrame) -> pd.DataFrame:
    """The frontier's rows (FRONTIER): the shipped preset, its matrix band's lower edge moved, and
    the fits from it, each with its fast-loop figures and values."""
    start = {n: v for n, v in zip(NAMES, preset_values())}
    rows = [{"variant": "preset", **fast_figures(build(start), table), **{f"param_{k}": v for k, v in start.items()}}]
    for hz in FRONTIER_BAND_MIN_HZ:
        rows.append({"variant": f"preset_matrix_from_{hz:g}_hz", **fast_figures(build(start, min_frequency_hz=hz), table),
                     **{f"param_{k}": v for k, v in start.items()}})
    for name, weights, moved in FRONTIER:
        print(f"frontier {name}:", flush=True)
        values, _ = fit({**start, **moved}, weights, table, None, FRONTIER_EVALUATIONS)
        rows.append({"variant": name, **fast_figures(build(values), table), **{f"param_{k}": v for k, v in values.items()}})
        print("    " + ", ".join(f"{k} {v:.3g}" for k, v in rows[-1].items() if k != "variant"), flush=True)
    return pd.DataFrame(rows)


def preset_values() -> list[float]:
    """The shipped preset's fitted parameters (NAMES order), from its stored best candidate."""
    best = pd.read_csv(RESULTS / "nr60_candidates.csv").iloc[0]
    return [float(best[f"param_{n}"]) for n in NAMES]


PRESET = REPOSITORY / "rig_configs" / "couplings" / "rapp2022_nr60.toml"
RESULTS = REPOSITORY / "analysis" / "results"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("calibration_out"),
                    help="folder for the chosen coupling (rapp2022_nr60.toml), the candidates' table "
                         "(nr60_candidates.csv), the cross-validation and the undetermined directions "
                         "(default: calibration_out; the shipped preset is not touched)")
    ap.add_argument("--write-preset", action="store_true",
                    help="also write the chosen coupling over the repository's preset "
                         "rig_configs/couplings/rapp2022_nr60.toml and the tables into analysis/results/")
    ap.add_argument("--only", default=None, help="comma-separated candidate names (default: all)")
    ap.add_argument("--max-evaluations", type=int, default=80)
    ap.add_argument("--pipeline-rounds", type=int, default=0,
                    help="rounds of fast-loop fits corrected by a reduced full-pipeline campaign (default 0: "
                         "for this model the pipeline reads the fast loop's decays within 0.5 %%; the "
                         "candidates' figures always come from the pipeline)")
    ap.add_argument("--no-cross-validation", action="store_true",
                    help="skip Table 4 cross-validated by lever case (3 more fits)")
    ap.add_argument("--work", type=Path, default=Path("calibration_work"), help="folder for the pipeline runs")
    ap.add_argument("--frontier", action="store_true",
                    help="only the frontier between the decays' damping bias and the other targets (FRONTIER): "
                         "nr60_frontier.csv in --out (and in analysis/results/ with --write-preset)")
    args = ap.parse_args()
    table = pd.read_csv(table4_path())
    if args.frontier:
        rows = frontier(table)
        for folder in [args.out] + ([RESULTS] if args.write_preset else []):
            folder.mkdir(parents=True, exist_ok=True)
            rows.to_csv(folder / "nr60_frontier.csv", index=False)
        print(rows[["variant", "meets_all", "decay_vs_servo_damping_rms_pct", "table4_stiffness_rms_pct",
                    "table4_damping_rms_pct", "loss_factor_ratio_1hz_30hz", "storage_rise_pct_per_decade"]].to_string(index=False))
        return
    chosen = [c for c in CANDIDATES if args.only is None or c.name in args.only.split(",")]
    rows, flat_rows = [], []
    for cand in chosen:
        t0 = time.perf_counter()
        print(f"candidate {cand.name}:", flush=True)
        calibrate(cand, table, args.work / cand.name, args.pipeline_rounds, args.max_evaluations)
        missed, excess = target_excess(cand.figures)
        rows.append({"candidate": cand.name, "eligible": cand.eligible, "targets_missed": missed,
                     "target_excess": excess, **cand.figures,
                     **{f"param_{k}": v for k, v in cand.values.items()}, "wall_s": time.perf_counter() - t0})
        flat_rows += [{"candidate": cand.name, **f} for f in cand.flat]
        print("    " + ", ".join(f"{k} {v:.3g}" for k, v in cand.figures.items()), flush=True)
    trade = pd.DataFrame(rows).sort_values(["eligible", "targets_missed", "target_excess"], ascending=[False, True, True],
                                           kind="stable")
    best = next(c for c in chosen if c.name == trade.iloc[0]["candidate"])
    preset = build(best.values, best.weights.matrix)
    folders = [args.out] + ([RESULTS] if args.write_preset else [])
    tables = {"nr60_candidates.csv": trade, "nr60_undetermined_directions.csv": pd.DataFrame(flat_rows),
              "nr60_by_case.csv": by_case(preset, table)}
    if not args.no_cross_validation:
        tables["nr60_cross_validation.csv"] = cross_validate(table, best.weights, args.max_evaluations)
    for folder in folders:
        folder.mkdir(parents=True, exist_ok=True)
        for name, frame in tables.items():
            frame.to_csv(folder / name, index=False)
    (args.out / "rapp2022_nr60.toml").write_text(coupling_to_toml(preset))
    if args.write_preset:
        PRESET.write_text(coupling_to_toml(preset))
    print(trade[["candidate", "targets_missed", *TARGETS_COLUMNS]].to_string(index=False))
    for name, frame in tables.items():
        if name != "nr60_candidates.csv":
            print(f"{name}:\n{frame.to_string(index=False)}")
    print(f"wrote {', '.join(str(f) for f in folders)} (candidate {best.name})"
          + (f" and the preset {PRESET}" if args.write_preset else " (the preset unchanged: --write-preset writes it)"))


if __name__ == "__main__":
    main()
