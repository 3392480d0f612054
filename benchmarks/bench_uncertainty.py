"""Benchmark: the uncertainty budget of every drop of the Table-2 campaign (Rapp et al. 2022,
450 tests) against the campaign's extraction, measured in the same run.

Target: the budgets (GUM where Monte Carlo validates it, JCGM 101, 8) cost <= 2x the
extraction of the same logs. The campaign is simulated first (not timed); then every log is
read and extracted (the baseline, CPU time of this process: other jobs on the machine do not
stretch it), then the budgets run three ways on the same results:

- ``campaign_budgets``: Monte Carlo (adaptive, JCGM 101, 7.9) on the first drop of each
  condition, the GUM for the condition's other drops where it validated there;
- ``drop_budgets(method="gum")``: the law of propagation alone;
- ``drop_budgets(method="auto")``: both methods on every drop (the obvious route), timed on
  every 10th drop and scaled to all; on those drops the largest relative difference of U95
  between the two routes is printed too (the reuse's faithfulness; Monte Carlo's own
  numerical tolerance is 2 % of u).

The rig's input uncertainties are those of a calibrated lab rig: J 1 % per fixture, laser
radius 0.2 mm, laser calibration 0.3 % (rectangular), torque calibration 0.5 %, clock 0.3 Hz.

    python benchmarks/bench_uncertainty.py [--json benchmarks/results/uncertainty.json]
"""
from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from droptower.campaign import run_campaign
from droptower.configs import DEFAULT_COUPLING, DEFAULT_DOE, DEFAULT_RIG
from droptower.extract.files import Settings, extract_file
from droptower.rig.config import load_rig
from droptower.rig.uncertainty import override_uncertainty
from droptower.uncertainty import campaign_budgets, drop_budgets
from timing import json_option, write_figures


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workers", type=int, default=2)
    json_option(parser)
    args = parser.parse_args()
    rig = load_rig(DEFAULT_RIG)
    specs = [f"inertia_kgm2@{j}={0.01 * j}" for j in rig.inertias_kgm2]
    with tempfile.TemporaryDirectory(prefix="bench-uncertainty-") as tmp:
        folder = Path(tmp) / "table2"
        run_campaign(folder, DEFAULT_RIG, DEFAULT_COUPLING, DEFAULT_DOE, workers=args.workers, progress=False)
        logs = sorted((folder / "logs").iterdir())
        settings = Settings(rig=rig)
        t0 = time.process_time()
        extracted = [extract_file(p, settings) for p in logs]
        t_extract = time.process_time() - t0
        signals, results = [s for s, _ in extracted], [r for _, r in extracted]
        u = override_uncertainty(rig.uncertainty, [*specs, "laser_radius_m=0.0002", "laser_calibration_rel=0.003:rectangular",
                                                   "torque_calibration_rel=0.005", "sample_rate_hz=0.3"])
        metas = [s.metadata for s in signals]
        keys = [(round(r.inertia_kgm2, 6), s.metadata.get("drop_mass_kg"), s.metadata.get("drop_height_m"),
                 s.metadata.get("preload_nm")) for s, r in zip(signals, results)]
        t0 = time.process_time()
        budgets = campaign_budgets(results, u, conditions=keys, metadata=metas, rig=rig)
        t_campaign = time.process_time() - t0
        t0 = time.process_time()
        drop_budgets(results, u, metadata=metas, rig=rig, method="gum")
        t_gum = time.process_time() - t0
        every = slice(None, None, 10)
        t0 = time.process_time()
        full = drop_budgets(results[every], u, metadata=metas[every], rig=rig, method="auto")
        t_auto = (time.process_time() - t0) * len(results) / len(results[every])
    # faithfulness: the reused verdicts against both methods run on the drop itself
    worst = 0.0
    for b, f in zip(budgets[every], full):
        for name, q in f.quantities.items():
            if q.expanded_uncertainty > 0:
                worst = max(worst, abs(b[name].expanded_uncertainty - q.expanded_uncertainty) / q.expanded_uncertainty)
    n_mc = sum(b.trials > 0 for b in budgets)
    n_gum_validated = sum(all(q.method == "GUM" for q in b.quantities.values()) for b in budgets)
    figures = {
        "tests": len(results), "conditions": len(set(keys)), "extraction_cpu_s": round(t_extract, 3),
        "campaign_budgets_cpu_s": round(t_campaign, 3), "ratio_campaign_budgets_to_extraction": round(t_campaign / t_extract, 3),
        "gum_only_cpu_s": round(t_gum, 3), "ratio_gum_to_extraction": round(t_gum / t_extract, 3),
        "monte_carlo_every_drop_cpu_s_scaled": round(t_auto, 3),
        "ratio_monte_carlo_every_drop_to_extraction": round(t_auto / t_extract, 3),
        "drops_with_monte_carlo": n_mc,
        "max_relative_difference_U95_vs_monte_carlo_on_the_drop": round(worst, 4), "drops_all_quantities_gum": n_gum_validated,
        "target_ratio": 2.0,
    }
    for k, v in figures.items():
        print(f"{k:45s} {v}")
    write_figures(args.json, "uncertainty", figures)


if __name__ == "__main__":
    main()
