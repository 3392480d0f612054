"""Benchmark: the full Table-2 campaign (Rapp et al. 2022, 450 tests) simulated, logged and extracted.

Target: <= 60 s wall on this 2-core machine, peak memory <= 2 GB. Prints the wall
time, the CPU time per phase summed over the workers (simulation; sensor sampling and log
writing; reading back and extraction), peak memory of the main process and of the largest
worker (and their sum over all processes as an upper bound: forked workers share pages), and
the ratio to a baseline measured in the same run: the obvious loop, one test per
``simulate()`` call in one process (no batching, no workers), then write and extract, timed
on every 10th test of the plan and scaled to all of them.

    python benchmarks/bench_campaign.py [--workers N] [--coupling rapp2022_nr60] [--keep DIR]
"""
from __future__ import annotations

import argparse
import os
import shutil
import tempfile
import time
from pathlib import Path

from droptower.campaign import prepare, run_campaign
from droptower.campaign.executors import local_cores
from droptower.configs import DEFAULT_COUPLING, DEFAULT_DOE, DEFAULT_RIG
from droptower.extract.files import Settings, extract_file
from droptower.rig.simulate import as_tests, simulate
from timing import json_option, write_figures

TARGET_S = 60.0
TARGET_MB = 2048.0
BASELINE_EVERY = 10


def baseline(coupling: str, folder: Path) -> tuple[float, int, int]:
    """Seconds per test of the unbatched loop, the tests timed and the plan's size."""
    spec = prepare(DEFAULT_RIG, coupling, DEFAULT_DOE)
    tests = as_tests(spec.tests)
    sample = tests[::BASELINE_EVERY]
    simulate(spec.rig, spec.coupling, sample[:1], spec.duration_s)  # JIT warm-up, as the campaign had it
    settings = Settings(defaults={"lever_length_m": spec.rig.lever_length_m})
    t0 = time.perf_counter()
    for i, test in enumerate(sample):
        result = simulate(spec.rig, spec.coupling, [test], spec.duration_s)[0]
        path = result.write_log(folder / f"t{i}.parquet")
        try:
            extract_file(path, settings)
        except Exception:
            pass  # a failing test costs its time all the same
    return (time.perf_counter() - t0) / len(sample), len(sample), len(tests)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", type=int, default=None, help="local worker processes (default: every core)")
    ap.add_argument("--coupling", default=DEFAULT_COUPLING)
    ap.add_argument("--keep", type=Path, default=None, help="keep the campaign folder here")
    json_option(ap)
    args = ap.parse_args()

    tmp = Path(tempfile.mkdtemp(prefix="bench_campaign_"))
    out = args.keep or tmp / "campaign"
    try:
        t0 = time.perf_counter()
        run = run_campaign(out, DEFAULT_RIG, args.coupling, DEFAULT_DOE, workers=args.workers)
        wall = time.perf_counter() - t0
        workers = args.workers or local_cores()
        n = len(run.spec.tests)
        cpu = run.simulate_cpu_s + run.write_cpu_s + run.extract_cpu_s
        per_test, sampled, total = baseline(args.coupling, tmp)
        naive = per_test * total
        bound = run.peak_rss_main_mb + workers * run.peak_rss_worker_mb

        print(f"campaign: {n} tests ({run.spec.doe.name}), coupling {run.spec.coupling.name}, record "
              f"{run.spec.duration_s:g} s after the impact, {run.executor}, load average {os.getloadavg()[0]:.2f}")
        print(f"  wall time              {wall:7.1f} s   (target <= {TARGET_S:g} s: {'ok' if wall <= TARGET_S else 'MISSED'})"
              f"   {1e3 * wall / n:.1f} ms per test")
        print(f"  CPU per phase (summed over workers; {cpu:.1f} s):")
        for name, value in (("simulation", run.simulate_cpu_s), ("sensors + writing logs", run.write_cpu_s),
                            ("reading back + extraction", run.extract_cpu_s)):
            print(f"    {name:<26}{value:7.1f} s  {100 * value / cpu:5.1f} %  {1e3 * value / n:6.1f} ms per test")
        print(f"  peak memory            main {run.peak_rss_main_mb:.0f} MB, largest worker "
              f"{run.peak_rss_worker_mb:.0f} MB, all processes <= {bound:.0f} MB "
              f"(target <= {TARGET_MB:g} MB: {'ok' if bound <= TARGET_MB else 'MISSED'})")
        print(f"  results                {int((run.results['status'] == 'done').sum())} extracted, "
              f"{len(run.failed)} failed, {run.pending} pending")
        print(f"baseline (one test per simulate() call, one process; timed on {sampled} tests): "
              f"{1e3 * per_test:.1f} ms per test -> {naive:.1f} s for {total} tests")
        print(f"speed-up over the baseline: {naive / wall:.1f}x")
        write_figures(args.json, "bench_campaign", {
            "coupling": run.spec.coupling.name, "tests": n, "workers": workers, "wall_s": wall, "cpu_s": cpu,
            "peak_memory_bound_mb": bound, "baseline_s": naive, "speed_up": naive / wall})
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
        if args.keep is None:
            shutil.rmtree(out, ignore_errors=True)


if __name__ == "__main__":
    main()
