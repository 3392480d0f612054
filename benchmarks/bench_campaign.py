"""Benchmark: the full Table-2 campaign (Rapp et al. 2022, 450 tests) simulated, logged and extracted.

Target: 450 tests in <= 5 s wall with 2 workers on an unloaded 2-core machine, peak memory
<= 2 GB. Prints the wall time, the CPU per test of all processes (main and workers), the CPU
time per phase summed over the workers (simulation; sensor sampling and log writing; reading
back and extraction), the disk per test, peak memory of the main process and of the largest
worker (and their sum over all processes as an upper bound: forked workers share pages), and
the ratio to a baseline measured in the same run: the obvious loop, one test per
``simulate()`` call in one process (no batching, no workers), then write and extract, timed
on every 10th test of the plan and scaled to all of them.

``--n N`` runs the Table-2 plan with N / 90 repeats per condition instead of 5. ``--dask``
runs on a local Dask cluster of ``--workers`` (2) worker processes, one thread each: a 90-test
warm-up (the workers import and compile), the 450-test plan, then N tests on the same cluster;
the named baseline is then the 450-test run, and the figure is the ratio of the wall time per
test (target <= 1.15; 45 000 tests in <= 12 min unloaded, extrapolated at that rate when N is
smaller), with the client's and the workers' peak memory (and what N tests added to it after
the 450) and the disk per test (<= 90 kB). ``--json benchmarks/results/campaign_dask.json``
stores the figures (``analysis/readme_figures.py`` renders them into docs/benchmarks.md).

    python benchmarks/bench_campaign.py [--workers N] [--n 450] [--coupling rapp2022_nr60] [--keep DIR]
    python benchmarks/bench_campaign.py --dask --n 45000 --json benchmarks/results/campaign_dask.json
"""
from __future__ import annotations

import argparse
import os
import resource
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

TARGET_S = 5.0
TARGET_MB = 2048.0
TARGET_KB_PER_TEST = 90.0
TARGET_DASK_RATIO = 1.15
DASK_TARGET_TESTS = 45000
DASK_TARGET_S = 12 * 60.0
BASELINE_EVERY = 10
TABLE2_CONDITIONS = 90  # 3 cases x 10 heights x 3 preloads


def baseline(coupling: str, folder: Path) -> tuple[float, float, int, int]:
    """Seconds per test of the unbatched loop (wall and CPU), the tests timed and the plan's size."""
    spec = prepare(DEFAULT_RIG, coupling, DEFAULT_DOE)
    tests = as_tests(spec.tests)
    sample = tests[::BASELINE_EVERY]
    simulate(spec.rig, spec.coupling, sample[:1], spec.duration_s)  # JIT warm-up, as the campaign had it
    settings = Settings(defaults={"lever_length_m": spec.rig.lever_length_m})
    t0, c0 = time.perf_counter(), time.process_time()
    for i, test in enumerate(sample):
        result = simulate(spec.rig, spec.coupling, [test], spec.duration_s)[0]
        path = result.write_log(folder / f"t{i}.parquet")
        try:
            extract_file(path, settings)
        except Exception:
            pass  # a failing test costs its time all the same
    return ((time.perf_counter() - t0) / len(sample), (time.process_time() - c0) / len(sample), len(sample),
            len(tests))


def plan_of(n: int, folder: Path) -> Path | str:
    """The Table-2 plan with n / 90 repeats per condition (the shipped plan itself for n = 450)."""
    from droptower.configs import read_toml, resolve

    if n == 450:
        return DEFAULT_DOE
    repeats, rest = divmod(n, TABLE2_CONDITIONS)
    if rest or repeats < 1:
        raise SystemExit(f"--n must be a multiple of {TABLE2_CONDITIONS} (the Table-2 conditions), got {n}")
    text = resolve(DEFAULT_DOE, "doe").read_text()
    assert read_toml(resolve(DEFAULT_DOE, "doe"))["repeats"] == 5
    path = folder / f"table2_x{repeats}.toml"
    path.write_text(text.replace("repeats = 5", f"repeats = {repeats}", 1).replace(
        'name = "rapp2022_table2"', f'name = "rapp2022_table2_{n}"', 1))
    return path


def cpu_s() -> float:
    """CPU time (user + system) of this process and its finished children."""
    own, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def disk_kb_per_test(out: Path, n: int) -> float:
    return sum(p.stat().st_size for sub in ("logs", "records") for p in (out / sub).iterdir()) / n / 1e3


def report(run, wall: float, cpu: float | None, out: Path) -> dict[str, float]:
    n = len(run.spec.tests)
    phases = run.simulate_cpu_s + run.write_cpu_s + run.extract_cpu_s
    kb = disk_kb_per_test(out, n)
    print(f"campaign: {n} tests ({run.spec.doe.name}, chunks of {run.spec.chunk_size}), coupling "
          f"{run.spec.coupling.name}, record {run.spec.duration_s:g} s after the impact, {run.executor}, "
          f"load average {os.getloadavg()[0]:.2f}")
    print(f"  wall time              {wall:7.1f} s   {1e3 * wall / n:.1f} ms per test")
    if cpu is not None:
        print(f"  CPU, all processes     {cpu:7.1f} s   {1e3 * cpu / n:.1f} ms per test")
    print(f"  CPU per phase (summed over workers; {phases:.1f} s):")
    for name, value in (("simulation", run.simulate_cpu_s), ("sensors + writing logs", run.write_cpu_s),
                        ("reading back + extraction", run.extract_cpu_s)):
        print(f"    {name:<26}{value:7.1f} s  {100 * value / phases:5.1f} %  {1e3 * value / n:6.1f} ms per test")
    print(f"  disk                   {kb:.1f} kB per test (logs and records; target <= {TARGET_KB_PER_TEST:g} kB: "
          f"{'ok' if kb <= TARGET_KB_PER_TEST else 'MISSED'})")
    print(f"  results                {int((run.results['status'] == 'done').sum())} extracted, "
          f"{len(run.failed)} failed, {run.pending} pending, {len(run.errors)} chunk errors")
    return {"tests": n, "wall_s": wall, "cpu_s": cpu, "phases_cpu_s": phases, "disk_kb_per_test": kb}


def run_dask(args: argparse.Namespace, tmp: Path) -> None:
    from distributed import LocalCluster

    workers = args.workers or 2
    figures: dict[str, object] = {"coupling": args.coupling, "workers": workers}
    with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        # the workers import and compile on their first chunks: a small campaign first, so that
        # neither timed run pays that (it would flatter the ratio, the 450 tests paying it all)
        run_campaign(tmp / "warm_up", DEFAULT_RIG, args.coupling, plan_of(TABLE2_CONDITIONS, tmp),
                     scheduler=cluster.scheduler_address, progress=False)
        shutil.rmtree(tmp / "warm_up", ignore_errors=True)
        walls, cpus = {}, {}
        for label, n in (("baseline", 450), ("campaign", args.n)):
            out = (args.keep or tmp) / f"dask_{n}"
            t0 = time.perf_counter()
            run = run_campaign(out, DEFAULT_RIG, args.coupling, plan_of(n, tmp), scheduler=cluster.scheduler_address,
                               progress=args.progress)
            wall = time.perf_counter() - t0
            print(f"[{label}]")
            figures[label] = report(run, wall, None, out)
            # peak resident memory since each process started (so the second run's figures bound both)
            print(f"  peak memory            client {run.peak_rss_main_mb:.0f} MB (the scheduler runs in it), "
                  f"largest worker {run.peak_rss_worker_mb:.0f} MB")
            figures[label] |= {"client_peak_mb": run.peak_rss_main_mb, "worker_peak_mb": run.peak_rss_worker_mb,
                               "load_average_end": round(os.getloadavg()[0], 2)}
            walls[label] = wall / n
            cpus[label] = figures[label]["phases_cpu_s"] / n
            if args.keep is None:
                shutil.rmtree(out, ignore_errors=True)
    ratio = walls["campaign"] / walls["baseline"]
    print(f"baseline (the 450-test plan on the same cluster): {1e3 * walls['baseline']:.1f} ms per test")
    print(f"per-test wall time, {args.n} tests / 450 tests: {ratio:.3f} "
          f"(target <= {TARGET_DASK_RATIO:g}: {'ok' if ratio <= TARGET_DASK_RATIO else 'MISSED'})")
    cpu_ratio = cpus["campaign"] / cpus["baseline"]
    print(f"per-test CPU of the workers, {args.n} tests / 450 tests: {cpu_ratio:.3f} (what the machine's other "
          f"jobs do not stretch)")
    growth = {k: figures["campaign"][f"{k}_peak_mb"] - figures["baseline"][f"{k}_peak_mb"] for k in ("client", "worker")}
    print(f"peak memory added by {args.n} tests after 450: client {growth['client']:+.0f} MB, "
          f"largest worker {growth['worker']:+.0f} MB")
    full = walls["campaign"] * DASK_TARGET_TESTS
    print(f"{DASK_TARGET_TESTS} tests at this rate: {full / 60:.1f} min (target <= {DASK_TARGET_S / 60:g} min on an "
          f"unloaded machine: {'ok' if full <= DASK_TARGET_S else 'MISSED (compare the load average)'}"
          f"{'' if args.n == DASK_TARGET_TESTS else f'; extrapolated from {args.n} tests'})")
    figures |= {"tests": args.n, "per_test_ratio": ratio, "per_test_cpu_ratio": cpu_ratio,
                "client_growth_mb": growth["client"], "worker_growth_mb": growth["worker"],
                "wall_s_for_target_tests": full, "target_tests": DASK_TARGET_TESTS}
    write_figures(args.json, "bench_campaign_dask", figures)


def run_local(args: argparse.Namespace, tmp: Path) -> None:
    out = args.keep or tmp / "campaign"
    c0, t0 = cpu_s(), time.perf_counter()
    run = run_campaign(out, DEFAULT_RIG, args.coupling, plan_of(args.n, tmp), workers=args.workers,
                       progress=args.progress)
    wall, cpu = time.perf_counter() - t0, cpu_s() - c0
    workers = args.workers or local_cores()
    n = len(run.spec.tests)
    figures = report(run, wall, cpu, out)
    bound = run.peak_rss_main_mb + workers * run.peak_rss_worker_mb
    print(f"  peak memory            main {run.peak_rss_main_mb:.0f} MB, largest worker "
          f"{run.peak_rss_worker_mb:.0f} MB, all processes <= {bound:.0f} MB "
          f"(target <= {TARGET_MB:g} MB: {'ok' if bound <= TARGET_MB else 'MISSED'})")
    print(f"  target                 <= {TARGET_S:g} s wall for 450 tests on an unloaded 2-core machine: "
          f"{'ok' if wall <= TARGET_S * n / 450 else 'MISSED (compare the load average)'}")
    per_test, cpu_per_test, sampled, total = baseline(args.coupling, tmp)
    naive = per_test * n
    print(f"baseline (one test per simulate() call, one process; timed on {sampled} tests): "
          f"{1e3 * per_test:.1f} ms per test -> {naive:.1f} s for {n} tests; CPU {1e3 * cpu_per_test:.1f} ms per test")
    print(f"speed-up over the baseline: {naive / wall:.1f}x wall, {cpu_per_test * n / cpu:.1f}x CPU per test "
          f"(the CPU figure is what the machine's other jobs do not stretch)")
    write_figures(args.json, "bench_campaign", figures | {
        "coupling": run.spec.coupling.name, "workers": workers, "peak_memory_bound_mb": bound,
        "baseline_s": naive, "speed_up": naive / wall, "baseline_cpu_ms_per_test": 1e3 * cpu_per_test,
        "cpu_ms_per_test": 1e3 * cpu / n, "cpu_speed_up": cpu_per_test * n / cpu})


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", type=int, default=None, help="worker processes (default: every core; Dask: 2)")
    ap.add_argument("--n", type=int, default=450, help="tests: the Table-2 plan with n / 90 repeats (default 450)")
    ap.add_argument("--dask", action="store_true", help="on a local Dask cluster, against 450 tests on it")
    ap.add_argument("--coupling", default=DEFAULT_COUPLING)
    ap.add_argument("--keep", type=Path, default=None, help="keep the campaign folder(s) here")
    ap.add_argument("--progress", action="store_true", help="show the campaign's progress bar (with its ETA)")
    json_option(ap)
    args = ap.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="bench_campaign_"))
    try:
        (run_dask if args.dask else run_local)(args, tmp)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
