"""Campaigns at scale on a local Dask cluster (2 worker processes), at a small size: a worker
killed mid-run loses no test, and a killed client resumes to the same results; the submission
window keeps the number of chunks in flight bounded, on the client and on the scheduler; the
estimate before a run."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pandas as pd
import pytest
from hypothesis import given, seed, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from droptower.campaign import run_campaign
from droptower.campaign.executors import WINDOW_PER_WORKER, LocalPool
from test_campaign import LINEAR
from test_campaign import PLAN as SMALL_PLAN

# the plan of test_campaign with 4 repeats: 16 tests in 8 chunks of 2, enough chunks in flight on
# both workers when one is killed
PLAN = SMALL_PLAN.replace("repeats = 2", "repeats = 4", 1).replace("base_seed = 100", "base_seed = 280", 1)
assert PLAN != SMALL_PLAN and "repeats = 4" in PLAN
SETTINGS = dict(duration_s=0.07, chunk_size=2, progress=False)
N_TESTS = 16


@pytest.fixture(scope="module")
def inputs(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("inputs")
    files = {"coupling": root / "linear.toml", "doe": root / "sixteen.toml"}
    files["coupling"].write_text(LINEAR)
    files["doe"].write_text(PLAN)
    return files


@pytest.fixture(scope="module")
def reference(inputs, tmp_path_factory):
    return run_campaign(tmp_path_factory.mktemp("reference") / "c", coupling=inputs["coupling"], doe=inputs["doe"],
                        workers=1, **SETTINGS)


@pytest.fixture(scope="module")
def cluster():
    # imported here, not at the module's top: every xdist worker collects this file, and Dask's
    # import (~1 s) is then paid only by the worker that runs a test on the cluster
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as c:
        yield c


def _records(out: Path) -> int:
    return len(list((out / "records").glob("*.json"))) if (out / "records").is_dir() else 0


@pytest.mark.slow
def test_worker_killed_mid_run_loses_no_test(inputs, reference, cluster, tmp_path):
    out = tmp_path / "killed_worker"
    result: dict = {}

    def campaign() -> None:
        try:
            result["run"] = run_campaign(out, coupling=inputs["coupling"], doe=inputs["doe"],
                                         scheduler=cluster.scheduler_address, **SETTINGS)
        except BaseException as exc:  # reported by the assertion below
            result["error"] = exc

    from distributed import Client

    with Client(cluster.scheduler_address, set_as_default=False) as client:
        pids = client.run(os.getpid)
        thread = threading.Thread(target=campaign)
        thread.start()
        killed = None
        deadline = time.monotonic() + 120
        while killed is None and thread.is_alive() and time.monotonic() < deadline:
            busy = [w for w, keys in client.processing().items() if keys]
            if busy and _records(out) >= 1:
                killed = pids[busy[0]]
                os.kill(killed, signal.SIGKILL)  # its chunks go to the other worker (or its restart)
            time.sleep(0.02)
        thread.join(timeout=300)
    assert killed is not None, "the campaign finished before a worker could be killed"
    assert "error" not in result, result.get("error")
    run = result["run"]
    assert _records(out) == N_TESTS and run.pending == 0 and not run.errors
    pd.testing.assert_frame_equal(run.results, reference.results, check_exact=True)


@pytest.mark.slow
def test_killed_client_resumes_on_the_cluster_to_the_same_results(inputs, reference, cluster, tmp_path):
    out = tmp_path / "killed_client"
    cmd = [sys.executable, "-m", "droptower.cli.main", "campaign", "--coupling", str(inputs["coupling"]),
           "--doe", str(inputs["doe"]), "--out", str(out), "--duration-s", "0.07", "--chunk-size", "2",
           "--scheduler", cluster.scheduler_address]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 120
        while _records(out) < 1 and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.01)
        proc.send_signal(signal.SIGKILL)
    finally:
        proc.wait()
    done = _records(out)
    assert 1 <= done < N_TESTS, "the kill came too late to interrupt the campaign"
    # the chunks the dead client left on the cluster are dropped with its futures: wait for that
    # (the scheduler notices the closed connection at once; the limit is a hung cluster's, not a timing)
    deadline = time.monotonic() + 60
    while cluster.scheduler.tasks and time.monotonic() < deadline:
        time.sleep(0.02)
    assert not cluster.scheduler.tasks, f"{len(cluster.scheduler.tasks)} chunks of the killed client still held"
    run = run_campaign(out, coupling=inputs["coupling"], doe=inputs["doe"], resume=True,
                       scheduler=cluster.scheduler_address, **SETTINGS)
    assert run.pending == 0 and _records(out) == N_TESTS
    pd.testing.assert_frame_equal(run.results, reference.results, check_exact=True)


def test_local_pool_keeps_a_bounded_window_of_chunks_in_flight():
    """The pool never holds more than WINDOW_PER_WORKER chunks per worker: with 2 workers, 100
    tasks, the pending ones at any yield are at most 8 (all tasks are run, each once)."""
    seen = []
    with LocalPool(2) as pool:
        for task, outcome in pool.run(abs, range(-100, 0)):
            seen.append((task, outcome))
            assert len(pool.pool._pending_work_items) <= WINDOW_PER_WORKER * 2
    assert sorted(t for t, _ in seen) == list(range(-100, 0)) and all(o == -t for t, o in seen)


@pytest.mark.slow
def test_dask_client_and_scheduler_hold_a_bounded_window_whatever_the_plan(cluster):
    """200 tasks on the 2-worker cluster: at every yield the client holds at most
    WINDOW_PER_WORKER chunks per worker (plus the one being released), and so does the scheduler (finished ones are released,
    not kept): memory and scheduling per chunk do not grow with the plan. Every task runs once."""
    from droptower.campaign.executors import DaskCluster

    executor = DaskCluster(cluster.scheduler_address)
    try:
        seen, held = [], []
        for task, outcome in executor.run(abs, range(-200, 0)):
            seen.append((task, outcome))
            held.append((len(executor.client.futures), len(cluster.scheduler.tasks)))
        assert sorted(t for t, _ in seen) == list(range(-200, 0)) and all(o == -t for t, o in seen)
        # the window, and the chunk just yielded whose release is on its way to the scheduler
        assert max(max(c, s) for c, s in held) <= WINDOW_PER_WORKER * 2 + 1, max(held)
    finally:
        executor.close()


def _bytes(folder: Path) -> int:
    return sum(p.stat().st_size for p in folder.rglob("*") if p.is_file())


@pytest.mark.slow
def test_estimate_before_running_is_close_to_what_the_campaign_writes(inputs, reference, tmp_path, capsys):
    """The disk estimate (the first chunk's files, scaled) within 10 % of the finished campaign's
    logs and records; after an interrupted run it counts only the tests still to run; the
    folder is not written."""
    from droptower.campaign import estimate_campaign
    from droptower.cli.main import main

    figures = estimate_campaign(tmp_path / "new", coupling=inputs["coupling"], doe=inputs["doe"], workers=2,
                                duration_s=0.07, chunk_size=2)
    written = _bytes(reference.root / "logs") + _bytes(reference.root / "records")
    per_test = (figures.log_bytes_per_test + figures.record_bytes_per_test) * N_TESTS
    assert abs(per_test - written) <= 0.1 * written, (per_test, written)
    assert figures.to_run == N_TESTS and figures.sample_tests == 2 and figures.cpu_per_test_s > 0
    assert figures.wall_s == pytest.approx(N_TESTS * figures.cpu_per_test_s / min(2, figures.cores))
    assert not (tmp_path / "new").exists()

    out = tmp_path / "part"
    run_campaign(out, coupling=inputs["coupling"], doe=inputs["doe"], workers=1, max_chunks=3, **SETTINGS)
    before = _bytes(out)
    assert main(["campaign", "--out", str(out), "--resume", "--estimate", "--workers", "1"]) in (0, None)
    text = capsys.readouterr().out
    assert f"{N_TESTS - 6} of {N_TESTS} tests to run" in text and "MB" in text and "ms CPU per test" in text
    assert _bytes(out) == before


@pytest.mark.parametrize("seed", range(5))
def test_results_assembled_in_batches_equal_those_assembled_at_once(reference, seed):
    """Random cuts of the records into batches (some holding only failed tests, without any
    extracted value) give the table that all records at once give, column for column."""
    import json

    import numpy as np

    from droptower.campaign.results import assemble, assemble_batches

    records = [json.loads(p.read_text()) for p in sorted((reference.root / "records").glob("*.json"))]
    rng = np.random.default_rng(seed)
    for k in rng.choice(len(records), size=4, replace=False):  # failed simulations: no result, no log
        records[k] = {**records[k], "status": "failed", "result": None, "log_file": None, "error": "simulation: x"}
    cuts = np.sort(rng.choice(np.arange(1, len(records)), size=rng.integers(1, 6), replace=False))
    batches = [list(part) for part in np.split(np.array(records, dtype=object), cuts)]
    pd.testing.assert_frame_equal(assemble_batches(batches), assemble(records), check_exact=True)


# ---- compact logs ------------------------------------------------------------------------------


# every magnitude, each with three seeded random lengths and value sets (each example is one parquet
# write and three reads, ~0.3 s; 25 draws over the magnitudes spent more to cover the same cases)
@pytest.mark.parametrize("scale", [1e-6, 1e-2, 1.0, 1e4, 2e5])
@seed(28)
@settings(max_examples=3, deadline=None)
@given(n=st.integers(2, 300), data=st.data())
def test_compact_log_reads_back_as_float32_values_in_every_reader(tmp_path_factory, scale, n, data):
    """A compact log (float32 channels, float64 time, zstd) reads back, in droptower's reader and
    in pandas/pyarrow, as exactly the float32-rounded channels and the exact time; metadata kept."""
    import numpy as np
    import pyarrow.parquet as pq

    from droptower.io.droptower_log import read_log, write_log

    time_s = np.arange(n) / 38400.0 - 0.005
    values = data.draw(arrays(np.float64, n, elements=st.floats(-1.0, 1.0, allow_nan=False))) * scale
    channels = {"angle_rad": values, "torque_nm": -values}
    path = tmp_path_factory.mktemp("compact") / "t.parquet"
    write_log(path, time_s, channels, {"seed": 7, "note": "x"}, compact=True)
    record = read_log(path)
    assert record.metadata == {"seed": 7, "note": "x"}
    np.testing.assert_array_equal(record.channels["time_s"].values, time_s)
    for name, v in channels.items():
        got = record.channels[name].values
        assert got.dtype == np.float64
        np.testing.assert_array_equal(got, v.astype(np.float32).astype(np.float64))
        # float32 rounding, nothing more (below float32's smallest normal number a value may flush to
        # zero: 1e-38 of any sensor's unit is no measurement)
        np.testing.assert_allclose(got, v, rtol=2 ** -24, atol=float(np.finfo(np.float32).tiny))
    frame = pd.read_parquet(path)
    assert list(frame.columns) == ["time_s", "angle_rad", "torque_nm"] and str(frame["angle_rad"].dtype) == "float32"
    np.testing.assert_array_equal(frame["torque_nm"].to_numpy(), (-values).astype(np.float32))
    assert pq.ParquetFile(path).metadata.row_group(0).column(1).compression == "ZSTD"
