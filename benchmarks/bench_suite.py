"""Where the test suite's wall time goes: a timeline of ``python -m pytest -n 2 -q`` per worker.

    python benchmarks/bench_suite.py [--cold] [--keep DIR] [--json PATH] [-- PYTEST ARGS]

Runs the suite (default arguments ``-n 2 -q``; anything after ``--`` replaces them) with the plugin
``benchmarks/suite_timeline.py`` and prints, per worker: start-up, collection, time in tests, idle
gaps between tests, the tail (from its last test to the end of the run) and numba's compilations
(wall and CPU, the heaviest named); then the last tests to start, and kernels compiled by more
than one worker. ``--cold`` deletes the compiled kernels first (the package's cache folders,
:func:`droptower.rheology.numba_cache.kernel_cache_root`; as on a fresh machine or in CI).

Baseline, measured in the same run: the balanced test time, the sum of every test's wall time
(setup, call, teardown) divided by the number of workers: what the run would take with no
start-up, no collection, no idle worker. The printed ratio is wall / balanced test time.
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

from timing import json_option, write_figures

REPO = Path(__file__).resolve().parents[1]
HERE = Path(__file__).resolve().parent
GAP_S = 0.5  # a pause between two tests of one worker longer than this is listed as idle


def read_timeline(folder: Path) -> list[dict]:
    """Every event of every process of one run, in time order."""
    events = [json.loads(line) for path in sorted(folder.glob("*.jsonl")) for line in path.read_text().splitlines()]
    return sorted(events, key=lambda e: e["t"])


def analyse(events: list[dict]) -> dict:
    """The figures of one run's timeline (``suite_timeline.py``'s events), in seconds.

    Returns ``wall_s`` (controller start to end), ``balanced_test_s`` (sum of the workers' test
    wall times / workers), ``workers`` (per worker: ``startup_s``, ``collection_s``, ``tests``,
    ``in_tests_s``, ``idle_s`` (pauses between tests, the wait before the first test included),
    ``gaps`` (those over ``GAP_S``: start relative to the run, length, the test that followed),
    ``tail_s`` (last test's end to the run's end), ``compile_s``, ``compile_cpu_s``,
    ``compiles`` (top-level compilations: function, start, wall, CPU)), ``last_started`` (the
    five tests that started last: test, worker, start, duration) and ``compiled_twice``
    (functions compiled at top level by more than one worker).
    """
    by_worker: dict[str, list[dict]] = defaultdict(list)
    for e in events:
        by_worker[e["worker"]].append(e)
    control = by_worker.pop("controller", []) if len(by_worker) > 1 else []  # without -n it runs the tests
    starts = [e["t"] if e.get("process_start") is None else e["process_start"] for e in events if e["event"] == "process_start"]
    t0 = min(starts, default=events[0]["t"])
    t_end = max(e["t"] for e in (control or events))
    workers, tests = {}, []
    compiled_by: dict[str, set[str]] = defaultdict(set)
    for name, evs in sorted(by_worker.items()):
        first = {e["event"]: e for e in reversed(evs)}
        begun = next((e["process_start"] for e in evs if e["event"] == "process_start"), None)
        begun = evs[0]["t"] if begun is None else begun
        collected = first.get("collection_finish", evs[0])["t"]
        runs, open_test, open_compile = [], {}, {}
        compiles = []
        for e in evs:
            if e["event"] == "test_start":
                open_test[e["test"]] = e
            elif e["event"] == "test_finish" and e["test"] in open_test:
                s = open_test.pop(e["test"])
                runs.append((s["t"], e["t"], e["test"]))
            elif e["event"] == "compile_start":
                open_compile[(e["function"], e["depth"])] = e
            elif e["event"] == "compile_end" and e["depth"] == 0 and (e["function"], 0) in open_compile:
                s = open_compile.pop((e["function"], 0))
                compiles.append({"function": e["function"], "start_s": round(s["t"] - t0, 2),
                                 "wall_s": round(e["t"] - s["t"], 2), "cpu_s": round(e["cpu"] - s["cpu"], 2)})
                compiled_by[e["function"]].add(name)
        runs.sort()
        gaps, idle = [], 0.0
        previous_end = collected
        for start, end, test in runs:
            pause = start - previous_end
            idle += max(pause, 0.0)
            if pause > GAP_S:
                gaps.append({"start_s": round(previous_end - t0, 2), "length_s": round(pause, 2), "before": test})
            previous_end = max(previous_end, end)
        tests += [{"test": test, "worker": name, "start_s": round(start - t0, 2), "duration_s": round(end - start, 2)}
                  for start, end, test in runs]
        workers[name] = {
            "startup_s": round(first.get("collection_start", evs[0])["t"] - begun, 2),
            "collection_s": round(collected - first.get("collection_start", evs[0])["t"], 2),
            "tests": len(runs),
            "in_tests_s": round(sum(end - start for start, end, _ in runs), 2),
            "idle_s": round(idle, 2),
            "gaps": gaps,
            "tail_s": round(t_end - previous_end, 2),
            "compile_s": round(sum(c["wall_s"] for c in compiles), 2),
            "compile_cpu_s": round(sum(c["cpu_s"] for c in compiles), 2),
            "compiles": sorted(compiles, key=lambda c: -c["wall_s"]),
        }
    n = max(len(workers), 1)
    return {
        "wall_s": round(t_end - t0, 2),
        "balanced_test_s": round(sum(w["in_tests_s"] for w in workers.values()) / n, 2),
        "workers": workers,
        "last_started": sorted(tests, key=lambda r: -r["start_s"])[:5],
        "compiled_twice": sorted(f for f, who in compiled_by.items() if len(who) > 1),
    }


def delete_numba_cache() -> int:
    """Delete the compiled kernels: the package's cache folders (every version's) and numba's cache
    files beside the sources (where a kernel falls back to them); returns how many files."""
    sys.path.insert(0, str(REPO))
    from droptower.rheology.numba_cache import kernel_cache_root

    folders = [p for p in kernel_cache_root().glob("droptower.*") if p.is_dir()]
    beside = [*REPO.glob("droptower/**/__pycache__/*.nbi"), *REPO.glob("droptower/**/__pycache__/*.nbc")]
    count = len(beside) + sum(len(list(folder.glob("*.nb[ic]"))) for folder in folders)
    for path in beside:
        path.unlink()
    for folder in folders:
        shutil.rmtree(folder, ignore_errors=True)
    return count


def report(figures: dict, cpu_s: float) -> None:
    wall, balanced = figures["wall_s"], figures["balanced_test_s"]
    print(f"wall {wall:.1f} s; balanced test time {balanced:.1f} s; ratio wall / balanced {wall / balanced:.2f}; "
          f"CPU of all processes {cpu_s:.1f} s; load average {os.getloadavg()[0]:.1f} at the end")
    for name, w in figures["workers"].items():
        print(f"{name}: start-up {w['startup_s']:.1f} s, collection {w['collection_s']:.1f} s, {w['tests']} tests "
              f"{w['in_tests_s']:.1f} s, idle between tests {w['idle_s']:.1f} s ({len(w['gaps'])} gaps > {GAP_S} s), "
              f"tail {w['tail_s']:.1f} s, numba compiling {w['compile_s']:.1f} s wall / {w['compile_cpu_s']:.1f} s CPU")
        for c in w["compiles"][:6]:
            print(f"    compiled {c['function']} at {c['start_s']:.0f} s: {c['wall_s']:.1f} s wall, {c['cpu_s']:.1f} s CPU")
        for g in sorted(w["gaps"], key=lambda g: -g["length_s"])[:3]:
            print(f"    idle {g['length_s']:.1f} s at {g['start_s']:.0f} s, before {g['before']}")
    print("last tests to start:")
    for r in figures["last_started"]:
        print(f"    {r['start_s']:7.1f} s  {r['duration_s']:6.1f} s  {r['worker']}  {r['test']}")
    print("compiled by more than one worker:", ", ".join(figures["compiled_twice"]) or "none")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cold", action="store_true", help="delete the compiled kernels first (a cold cache, as on a fresh machine)")
    parser.add_argument("--keep", type=Path, default=None, metavar="DIR", help="write the timeline files here (kept)")
    json_option(parser)
    args, rest = parser.parse_known_args()
    pytest_args = [a for a in rest if a != "--"] or ["-n", "2", "-q"]
    if args.cold:
        print(f"deleted {delete_numba_cache()} numba cache files")
    folder = args.keep or Path(tempfile.mkdtemp(prefix="suite-timeline-"))
    folder.mkdir(parents=True, exist_ok=True)
    env = {**os.environ, "SUITE_TIMELINE_DIR": str(folder), "MPLBACKEND": "Agg",
           "PYTHONPATH": os.pathsep.join(filter(None, [str(HERE), os.environ.get("PYTHONPATH")]))}
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t = time.perf_counter()
    code = subprocess.call([sys.executable, "-m", "pytest", "-p", "suite_timeline", *pytest_args], cwd=REPO, env=env)
    elapsed = time.perf_counter() - t
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    figures = analyse(read_timeline(folder))
    print(f"\npytest exit code {code}; {elapsed:.1f} s wall from here; timeline in {folder}")
    report(figures, cpu)
    write_figures(args.json, "suite", {"wall_s": figures["wall_s"], "balanced_test_s": figures["balanced_test_s"],
                                       "cpu_all_processes_s": round(cpu, 1), "cold_numba_cache": args.cold,
                                       "pytest_args": pytest_args, "workers": figures["workers"],
                                       "last_started": figures["last_started"]})


if __name__ == "__main__":
    main()
