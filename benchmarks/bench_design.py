"""Designing campaigns: `droptower design` and `design --for-identification`.

    python benchmarks/bench_design.py [--quick] [--couplings N]

1. Coverage design of the target 0.3-3 deg x 22-50 Hz on rig ``rapp2022`` with
   ``rapp2022_nr60``: wall time of the design; the designed plan run through the campaign (rig
   -> logs -> extraction, one repeat): conditions, drops, covered fraction, realised vs
   predicted amplitude and frequency (target: within 3 %), double impacts. Baseline in the same
   run: ``plan`` of Table 2 (450 conditions' worth of predictions, repeats collapsed: 90).
2. Design for identification: the reference coupling's structure as a template, identified
   from a designed 12-drop campaign (D-optimal, designed on the preset without knowing the
   truth) and from the 12-drop plan of ``bench_identify.py`` (three levers x heights 0.1-3 m),
   for the preset itself and for N couplings of the same structure with other numbers (every
   number scaled by a random factor 0.6-1.6, seeded): storage stiffness and loss factor of the
   identified model against the truth's on a servo grid inside the tested range; then the same
   for the identification benchmark's couplings of three other families (elastoslide,
   zerodim6-type, masing-type; tests/data/unknown_couplings.json), each designed for its own
   family on the truth (a locally optimal design assumes the best guess is right).
"""
from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd
import tomli_w

from droptower import load_coupling
from droptower.campaign import run_campaign
from droptower.design import Target, design_campaign, in_hull
from droptower.design.coverage import plane
from droptower.design.identification import design_for_identification
from droptower.design.outputs import coverage_description, write_doe
from droptower.identify.dropfit import identify_drops, servo_agreement
from droptower.identify.droplogs import ReadSettings, read_decays
from droptower.identify.families import family_class
from droptower.identify.families.base import DataScale
from droptower.rig.config import load_doe, load_rig
from droptower.rig.predictions import plan

TARGET = Target((0.3, 3.0), (22.0, 50.0))
#: The identification benchmark's couplings of three families (none a preset).
DROP_TRUTHS = json.loads((Path(__file__).resolve().parents[1] / "tests" / "data" / "unknown_couplings.json").read_text())
#: bench_identify.py's drop campaign: the three levers, four heights 0.1-3 m each.
REFERENCE_PLAN = pd.DataFrame([(j, m, h) for j, m in ((0.1557, 1.0), (0.359, 2.0), (0.5233, 2.0))
                               for h in (0.1, 0.4, 1.0, 3.0)], columns=["inertia_kgm2", "drop_mass_kg", "drop_height_m"])


def coverage(rig, coupling) -> None:
    t0 = time.perf_counter()
    plan(rig, coupling, load_doe("rapp2022_table2").conditions())
    t_plan = time.perf_counter() - t0
    t0 = time.perf_counter()
    d = design_campaign(rig, coupling, TARGET, repeats=1)
    t_design = time.perf_counter() - t0
    with tempfile.TemporaryDirectory() as tmp:
        doe = write_doe(d.conditions, Path(tmp) / "designed.toml", coverage_description(d))
        res = run_campaign(Path(tmp) / "run", "rapp2022", "rapp2022_nr60", doe, workers=2, progress=False).results
    keys = ["inertia_kgm2", "drop_mass_kg", "drop_height_m", "preload_nm"]
    m = d.conditions.merge(res, on=keys, suffixes=("_predicted", ""))
    da = np.abs(m["amplitude_deg"] / m["amplitude_deg_predicted"] - 1)
    df = np.abs(m["frequency_hz"] / m["frequency_hz_predicted"] - 1)
    grid = TARGET.grid()
    claimed = in_hull(plane(d.conditions["amplitude_deg"], d.conditions["frequency_hz"]), grid)
    realised = in_hull(plane(res["amplitude_deg"], res["frequency_hz"]), grid)
    print(f"design 0.3-3 deg x 22-50 Hz: {d.n_conditions} conditions, {d.n_tests} drops (1 repeat; 3 by default: "
          f"{3 * d.n_conditions}), covered {100 * d.covered_fraction:.1f} % of the target "
          f"(reachable {100 * d.reachable_fraction:.1f} %), realised hull covers {100 * realised.mean():.1f} % "
          f"(claimed points missed: {int(np.sum(claimed & ~realised))})")
    print(f"  realised vs predicted: amplitude max {100 * da.max():.2f} % (RMS {100 * np.sqrt(np.mean(da**2)):.2f} %), "
          f"frequency max {100 * df.max():.2f} % (RMS {100 * np.sqrt(np.mean(df**2)):.2f} %); double impacts "
          f"{int(res['double_impact'].sum())}")
    for line in d.unreachable:
        print(f"  unreachable: {line}")
    print(f"  design {t_design:.2f} s; baseline plan of Table 2 (90 conditions) {t_plan:.2f} s -> ratio "
          f"{t_design / t_plan:.1f}")


def variant(base, rng) -> dict:
    """The preset with every fitted number scaled by a random factor 0.6-1.6 (same structure)."""
    fam = family_class("template")(DataScale(1, 1, 1, 1, 1, 1), {"template": base})
    factors = np.exp(rng.uniform(np.log(0.6), np.log(1.6), len(fam.names)))
    return {"name": "variant", "units": "torsional", "element": fam.elements(factors)}


def identify_plan(truth_file: str | Path, conditions: pd.DataFrame, tmp: Path, label: str,
                  kind: str = "template") -> dict:
    rows = conditions.loc[conditions.index.repeat(conditions.get("repeats", 1))]
    doe = {"name": label, "repeats": 1, "heights_m": [1.0], "preloads_nm": [0.0],
           "group": [{"name": f"J {j:g}, m {m:g}", "inertia_kgm2": float(j), "drop_mass_kg": float(m),
                      "heights_m": [float(h) for h in g["drop_height_m"]]}
                     for (j, m), g in rows.groupby(["inertia_kgm2", "drop_mass_kg"])]}
    (tmp / f"{label}.toml").write_text(tomli_w.dumps(doe))
    run_campaign(tmp / label, "rapp2022", truth_file, tmp / f"{label}.toml", workers=2, progress=False)
    decays, excluded = read_decays([tmp / label], ReadSettings())
    t0 = time.perf_counter()
    options = {"template": "rapp2022_nr60"} if kind == "template" else None
    fit = identify_drops(kind, decays, excluded=excluded, options=options)
    agree = servo_agreement(fit.coupling, load_coupling(truth_file), decays)
    return {"tests": len(decays), "k_rms": agree["storage_stiffness_rms"], "eta_rms": agree["loss_factor_rms"],
            "wall_s": time.perf_counter() - t0}


def identification(rig, coupling, n_variants: int) -> None:
    t0 = time.perf_counter()
    ident = design_for_identification(rig, coupling, Target((0.1, 5.0), (15.0, 80.0)), "template", 12,
                                      reference=REFERENCE_PLAN)
    t_design = time.perf_counter() - t0
    p = ident.parameters
    better = int(np.sum(p["stderr"] < p["reference_stderr"]))
    print(f"design --for-identification template, 12 drops: {t_design:.1f} s; predicted standard errors smaller than "
          f"the 12-drop reference plan's for {better} of {len(p)} parameters (geometric mean ratio "
          f"{np.exp(np.mean(np.log(p['stderr'] / p['reference_stderr']))):.2f})")
    rng = np.random.default_rng(2026)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        truths = {"rapp2022_nr60": None} | {f"variant_{i + 1}": variant(coupling, rng) for i in range(n_variants)}
        for name, doc in truths.items():
            folder = tmp / name
            folder.mkdir()
            truth: str | Path = "rapp2022_nr60"  # the preset, by name
            if doc is not None:
                truth = folder / "truth.toml"
                truth.write_text(tomli_w.dumps(doc))
            for label, cond in (("designed", ident.conditions), ("reference", REFERENCE_PLAN.assign(repeats=1))):
                rows.append({"truth": name, "plan": label, **identify_plan(truth, cond, folder, label)})
        # the identification benchmark's couplings of other families (designed on the truth:
        # a locally optimal design assumes the best guess is right)
        for kind, doc in DROP_TRUTHS.items():
            folder = tmp / kind
            folder.mkdir()
            truth = folder / "truth.toml"
            truth.write_text(tomli_w.dumps(doc))
            designed = design_for_identification(rig, load_coupling(truth), Target((0.1, 5.0), (15.0, 80.0)), kind, 12)
            for label, cond in (("designed", designed.conditions), ("reference", REFERENCE_PLAN.assign(repeats=1))):
                rows.append({"truth": kind, "plan": label, **identify_plan(truth, cond, folder, label, kind)})
    table = pd.DataFrame(rows)
    with pd.option_context("display.width", 200, "display.float_format", "{:.4f}".format):
        print(table.to_string(index=False))
    for label, g in table.groupby("plan"):
        print(f"  {label}: K' RMS error median {100 * g['k_rms'].median():.2f} % (max {100 * g['k_rms'].max():.2f} %), "
              f"loss factor median {100 * g['eta_rms'].median():.2f} % (max {100 * g['eta_rms'].max():.2f} %); "
              f"within K' 3 % and loss factor 10 %: {int(((g['k_rms'] <= 0.03) & (g['eta_rms'] <= 0.10)).sum())} "
              f"of {len(g)}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="coverage design only")
    ap.add_argument("--couplings", type=int, default=4, help="random couplings of the preset's structure")
    args = ap.parse_args()
    rig, coupling = load_rig("rapp2022"), load_coupling("rapp2022_nr60")
    design_campaign(rig, coupling, TARGET)  # compile the kernels outside the timing
    coverage(rig, coupling)
    if not args.quick:
        identification(rig, coupling, args.couplings)


if __name__ == "__main__":
    main()
