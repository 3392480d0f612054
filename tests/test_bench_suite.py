"""The suite's timeline (``benchmarks/bench_suite.py``, plugin ``benchmarks/suite_timeline.py``):
its figures from a timeline whose answer is known, and the plugin's events from a real run."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"
sys.path.insert(0, str(BENCHMARKS))
import bench_suite  # noqa: E402  (a script folder, put on the path above)


def _event(event: str, worker: str, t: float, cpu: float = 0.0, **fields) -> dict:
    return {"event": event, "worker": worker, "t": t, "cpu": cpu, **fields}


def test_figures_of_a_timeline_whose_answer_is_known() -> None:
    """Two workers: gw0 collects 2 s, waits 1 s, runs a 4 s test that compiles for 3 s (CPU 2.5 s),
    pauses 0.2 s, runs a 1 s test; gw1 collects 3 s and runs one 2 s test, then waits 5.2 s
    for the run's end at 13 s, when the controller ends."""
    events = [
        _event("process_start", "controller", 0.5, process_start=0.0), _event("end", "controller", 13.0),
        _event("process_start", "gw0", 1.5, process_start=1.0), _event("collection_start", "gw0", 2.0),
        _event("collection_finish", "gw0", 4.0), _event("test_start", "gw0", 5.0, test="a"),
        _event("compile_start", "gw0", 5.5, 1.0, function="k", depth=0),
        _event("compile_start", "gw0", 6.0, 1.2, function="inner", depth=1),
        _event("compile_end", "gw0", 7.0, 2.0, function="inner", depth=1),
        _event("compile_end", "gw0", 8.5, 3.5, function="k", depth=0),
        _event("test_finish", "gw0", 9.0, test="a"), _event("test_start", "gw0", 9.2, test="b"),
        _event("test_finish", "gw0", 10.2, test="b"),
        _event("process_start", "gw1", 1.6, process_start=1.0), _event("collection_start", "gw1", 2.5),
        _event("collection_finish", "gw1", 5.5), _event("test_start", "gw1", 5.8, test="c"),
        _event("compile_start", "gw1", 6.0, 0.0, function="k", depth=0),
        _event("compile_end", "gw1", 7.0, 1.0, function="k", depth=0),
        _event("test_finish", "gw1", 7.8, test="c"),
    ]
    figures = bench_suite.analyse(sorted(events, key=lambda e: e["t"]))
    assert figures["wall_s"] == 13.0
    assert figures["balanced_test_s"] == pytest.approx((4.0 + 1.0 + 2.0) / 2)
    gw0, gw1 = figures["workers"]["gw0"], figures["workers"]["gw1"]
    assert (gw0["startup_s"], gw0["collection_s"], gw0["tests"]) == (1.0, 2.0, 2)
    assert gw0["in_tests_s"] == pytest.approx(5.0) and gw0["idle_s"] == pytest.approx(1.2)
    assert [g["length_s"] for g in gw0["gaps"]] == [1.0]  # the 0.2 s pause is under GAP_S
    assert gw0["tail_s"] == pytest.approx(2.8) and gw1["tail_s"] == pytest.approx(5.2)
    assert (gw0["compile_s"], gw0["compile_cpu_s"]) == (3.0, 2.5)  # the nested compilation is inside it
    assert [c["function"] for c in gw0["compiles"]] == ["k"]
    assert figures["compiled_twice"] == ["k"]
    assert [r["test"] for r in figures["last_started"]] == ["b", "c", "a"]


def test_the_plugin_records_collection_tests_and_numba_compilations(tmp_path: Path) -> None:
    (tmp_path / "test_one.py").write_text(
        "from numba import njit\n\n"
        "def test_compiles():\n"
        "    assert njit(lambda x: x + 1)(1) == 2\n")
    folder = tmp_path / "timeline"
    env = {**os.environ, "SUITE_TIMELINE_DIR": str(folder), "PYTEST_DISABLE_PLUGIN_AUTOLOAD": "1",
           "PYTHONPATH": os.pathsep.join(filter(None, [str(BENCHMARKS), os.environ.get("PYTHONPATH")]))}
    done = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "suite_timeline", "-p", "no:cacheprovider",
                           str(tmp_path / "test_one.py")], cwd=tmp_path, env=env, capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    events = bench_suite.read_timeline(folder)
    kinds = [e["event"] for e in events]
    assert kinds[0] == "process_start" and kinds[-1] == "end"
    assert kinds.index("collection_start") < kinds.index("collection_finish") < kinds.index("test_start")
    assert kinds.index("test_start") < kinds.index("compile_start") < kinds.index("compile_end") < kinds.index("test_finish")
    figures = bench_suite.analyse(events)
    (worker,) = figures["workers"].values()
    assert worker["tests"] == 1 and [c["function"] for c in worker["compiles"]] == ["test_one.test_compiles.<locals>.<lambda>"]
    assert 0 < worker["compiles"][0]["wall_s"] <= worker["in_tests_s"] <= figures["wall_s"]


def test_the_schedule_simulation_runs_every_test_once_on_xdists_schedulers() -> None:
    """``benchmarks/suite_schedule.py`` on random test times: each test runs once (the workers'
    time in tests adds up to the sum), no run ends before the balanced time or the longest test,
    and the slow-files-first order keeps each file's tests together and in their order."""
    import itertools
    import random

    import suite_schedule

    rng = random.Random(3)
    order = [f"tests/test_{f}.py::test_{i}" for f in "abcdefgh" for i in range(rng.randint(1, 40))]
    seconds = {test: rng.expovariate(1.0) * (20.0 if rng.random() < 0.05 else 1.0) for test in order}
    slow = {test for test in order if seconds[test] > 5.0}
    first = suite_schedule.heavy_files_first(order, slow)
    files = [test.split("::")[0] for test in first]
    blocks = [f for f, _ in itertools.groupby(files)]
    assert sorted(first) == sorted(order) and len(blocks) == len(set(blocks))  # one block per file
    assert [t for t in first if t.startswith("tests/test_a.py")] == [t for t in order if t.startswith("tests/test_a.py")]
    total = sum(seconds.values())
    for kind in ("load", "worksteal"):
        for case in (order, first):
            per_worker = suite_schedule.Simulation(kind, case, seconds, 2).run()
            assert sum(busy for busy, _ in per_worker.values()) == pytest.approx(total)
            assert max(end for _, end in per_worker.values()) >= max(total / 2, max(seconds.values())) - 1e-9
