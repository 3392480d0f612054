"""Profile of the campaign's per-test path: a serial run (one process) of the first ~50 tests of
the Table-2 campaign (Rapp et al. 2022) under cProfile, on the CPU clock of this process, so other
jobs on the machine do not stretch it. Prints the CPU per test by phase (simulation, sensors and
log writing, reading back and extraction, the rest: records, manifest, results table) and the
functions taking the most CPU; ``benchmarks/results/campaign_profile.txt`` keeps a printout.

    python benchmarks/profile_campaign.py [--tests 50] [--top 25]
"""
from __future__ import annotations

import argparse
import cProfile
import io
import pstats
import sysconfig
import tempfile
import time
from pathlib import Path

from droptower.campaign import run_campaign


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tests", type=int, default=50, help="tests to run (whole chunks of the default size)")
    ap.add_argument("--top", type=int, default=25, help="functions to list")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        warm = run_campaign(Path(tmp) / "warm", workers=1, max_chunks=1, progress=False)  # JIT compilation
        chunks = max(1, round(args.tests / warm.spec.chunk_size))
        profile = cProfile.Profile(time.process_time)
        t0 = time.process_time()
        profile.enable()
        run = run_campaign(Path(tmp) / "campaign", workers=1, max_chunks=chunks, progress=False)
        profile.disable()
        cpu = time.process_time() - t0
    n = run.ran_tests
    rest = cpu - run.simulate_cpu_s - run.write_cpu_s - run.extract_cpu_s
    print(f"serial campaign: {n} tests of {run.spec.doe.name} (chunks of {run.spec.chunk_size}), coupling "
          f"{run.spec.coupling.name}, log format {run.spec.log_format}; CPU (under cProfile) {cpu:.2f} s, "
          f"{1e3 * cpu / n:.1f} ms per test")
    for name, value in (("simulation", run.simulate_cpu_s), ("sensors + writing logs", run.write_cpu_s),
                        ("reading back + extraction", run.extract_cpu_s),
                        ("rest (plan, records, manifest, table)", rest)):
        print(f"  {name:<40}{1e3 * value / n:7.2f} ms per test")
    text = io.StringIO()
    stats = pstats.Stats(profile, stream=text)
    stats.sort_stats("tottime").print_stats(args.top)
    stats.sort_stats("cumulative").print_stats(args.top)
    listing = text.getvalue().replace(str(Path(__file__).resolve().parents[1]) + "/", "")
    listing = listing.replace(sysconfig.get_paths()["stdlib"] + "/", "<stdlib>/")  # no machine paths
    print("\n".join(line.rstrip() for line in listing.splitlines()
                    if line.strip() and not line.lstrip().startswith(("Ordered", "List reduced"))))


if __name__ == "__main__":
    main()
