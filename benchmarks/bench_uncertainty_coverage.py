"""Benchmark: coverage of the model route's expanded uncertainties on virtual campaigns whose
truth is known (tests/coverage_campaigns.py: a linear Kelvin-Voigt coupling, one rig per
campaign drawn from its stated uncertainties, J 1 % per fixture and the clock 0.2 %, shared by
every drop; the extraction on the nominal rig).

Target: the 95 % intervals of the route's servo K' and loss factor (at 10 Hz) contain the truth
in 95 % ± 2.5 % of the campaigns; the fit-only intervals (the inputs switched off) under-cover.
Prints the coverages, the binomial standard deviation, and the CPU time per campaign.

    python benchmarks/bench_uncertainty_coverage.py [--campaigns 2000] [--json benchmarks/results/uncertainty_coverage.json]
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from coverage_campaigns import coverage  # noqa: E402
from timing import json_option, write_figures  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--campaigns", type=int, default=2000)
    parser.add_argument("--drops-per-fixture", type=int, default=2)
    json_option(parser)
    args = parser.parse_args()
    t0 = time.process_time()
    shares = coverage(args.campaigns, seed=1_000_000, drops_per_fixture=args.drops_per_fixture)
    cpu = time.process_time() - t0
    figures = {"campaigns": args.campaigns, "drops_per_campaign": 3 * args.drops_per_fixture,
               "coverage_storage_stiffness": shares["k"], "coverage_loss_factor": shares["eta"],
               "coverage_storage_stiffness_fit_only": shares["k_fit"], "coverage_loss_factor_fit_only": shares["eta_fit"],
               "binomial_std_at_95pct": round(math.sqrt(0.95 * 0.05 / args.campaigns), 4),
               "target": "0.95 +- 0.025 with the inputs; fit-only under-covers",
               "cpu_s_per_campaign": round(cpu / args.campaigns, 4)}
    for k, v in figures.items():
        print(f"{k:40s} {v}")
    write_figures(args.json, "uncertainty_coverage", figures)


if __name__ == "__main__":
    main()
