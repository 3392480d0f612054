"""``droptower campaign``: one data path (simulate -> log on disk -> extract), closed-form values on a
linear coupling, determinism over workers, chunks and Dask, resume after an interruption or a
kill, and one-line errors that leave other campaigns' files alone."""
from __future__ import annotations

import hashlib
import json
import math
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from droptower.campaign import CampaignRun, run_campaign
from droptower.campaign.spec import PLAN_COLUMNS
from droptower.cli.main import main
from droptower.io import read_any
from pictures import assert_drawn

# Kelvin-Voigt coupling: the drop tower must give c = J (omega^2 + delta^2) = k and
# d_ratio = (exp(4 pi delta / omega) - 1) / 2 with delta = c_d / (2 J) (docs/theory.md#decay, #extraction).
K_NM_PER_RAD, C_NMS_PER_RAD = 14000.0, 8.0
LINEAR = f'name = "linear"\n[[element]]\nkind = "spring"\nstiffness = {K_NM_PER_RAD}\n' \
         f'[[element]]\nkind = "dashpot"\ndamping = {C_NMS_PER_RAD}\n'
STIFFER = LINEAR.replace(str(K_NM_PER_RAD), "15000.0")
# 8 tests: 2 heights x 2 preloads x 2 repeats; chunks of 3 -> chunks [0-2], [3-5], [6-7]
PLAN = """name = "small"
base_seed = 100
repeats = 2
heights_m = [0.2, 1.0]
preloads_nm = [0.0, 500.0]
[[group]]
name = "case 2"
inertia_kgm2 = 0.359
drop_mass_kg = 2.0
"""
J = 0.359
SETTINGS = dict(duration_s=0.07, chunk_size=3, progress=False)


@pytest.fixture(scope="session")  # kept when worksteal splits this file: a second block reuses it
def inputs(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("inputs")
    files = {"coupling": root / "linear.toml", "stiffer": root / "stiffer.toml", "doe": root / "small.toml"}
    files["coupling"].write_text(LINEAR)
    files["stiffer"].write_text(STIFFER)
    files["doe"].write_text(PLAN)
    return files


@pytest.fixture(scope="session")  # kept when worksteal splits this file: a second block reuses it
def reference(inputs, tmp_path_factory):
    """The uninterrupted campaign, in this process."""
    out = tmp_path_factory.mktemp("reference") / "campaign"
    run = run_campaign(out, coupling=inputs["coupling"], doe=inputs["doe"], workers=1, **SETTINGS)
    return run


def _snapshot(root: Path) -> dict[str, tuple[int, str]]:
    return {str(p.relative_to(root)): (p.stat().st_mtime_ns, hashlib.sha256(p.read_bytes()).hexdigest())
            for p in sorted(root.rglob("*")) if p.is_file()}


def _one_line_error(err: str) -> str:
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("droptower: error: "), err
    assert "Traceback" not in err
    return lines[0]


def _cli(inputs, out, *extra, coupling="coupling"):
    return main(["campaign", "--coupling", str(inputs[coupling]), "--doe", str(inputs["doe"]), "--out", str(out),
                 "--duration-s", "0.07", "--chunk-size", "3", *extra])


# ---- one data path, closed forms ------------------------------------------------------------
def test_pipeline_recovers_the_linear_coupling(reference):
    table, root = reference.results, reference.root
    assert reference.pending == 0 and not reference.failed and not reference.errors
    assert list(table.columns[:len(PLAN_COLUMNS)]) == list(PLAN_COLUMNS)
    assert list(table.columns[-5:]) == ["flags", "log_file", "status", "error", "simulation_warnings"]
    assert table["test_id"].tolist() == list(range(8))
    assert (table["status"] == "done").all()
    # closed forms of the damped single-degree-of-freedom oscillator (docs/theory.md#decay, #extraction)
    delta = C_NMS_PER_RAD / (2 * J)
    omega = math.sqrt(K_NM_PER_RAD / J - delta**2)
    np.testing.assert_allclose(table["stiffness_nm_per_rad"], K_NM_PER_RAD, rtol=1e-3)
    np.testing.assert_allclose(table["stiffness_nm_per_deg"], K_NM_PER_RAD * math.pi / 180, rtol=1e-3)
    np.testing.assert_allclose(table["frequency_hz"], omega / (2 * math.pi), rtol=1e-3)
    np.testing.assert_allclose(table["damping_ratio"], 0.5 * math.expm1(4 * math.pi * delta / omega), rtol=5e-3)
    # the amplitude grows with the drop height and not with the preload (a linear coupling)
    amp = table.groupby("drop_height_m")["amplitude_deg"]
    assert amp.max()[0.2] < amp.min()[1.0]
    assert (amp.max() / amp.min() - 1 < 1e-3).all()
    # every row points at its log, a real droptower log that any reader opens
    for row in table.itertuples():
        record = read_any(root / row.log_file)
        assert record.metadata["seed"] == row.seed and record.metadata["drop_height_m"] == row.drop_height_m
    # CSV and Parquet hold the same table (floats round-trip exactly through the CSV text)
    csv = pd.read_csv(root / "results.csv")
    for name in table.columns:
        if table[name].dtype.kind == "f":
            np.testing.assert_array_equal(csv[name].to_numpy(float), table[name].to_numpy(float), err_msg=name)
        else:
            assert csv[name].astype(object).fillna("").astype(str).tolist() == table[name].astype(str).tolist(), name
    manifest = json.loads((root / "manifest.json").read_text())
    assert manifest["summary"] == {"n_tests": 8, "done": 8, "failed": 0, "pending": 0}
    assert set(manifest["hashes"]) == {"rig", "coupling", "doe", "plan", "settings"}
    assert manifest["inputs"]["coupling"]["content"]["element"][0]["stiffness"] == K_NM_PER_RAD
    assert manifest["settings"] == {"duration_s": 0.07, "chunk_size": 3, "log_format": "parquet",
                                    "window": "first-cycle"}
    assert {"droptower", "numpy", "pymunk", "python"} <= set(manifest["versions"])


def test_cli_summary_and_exit_code(inputs, tmp_path, capsys):
    code = _cli(inputs, tmp_path / "c", "--workers", "1")
    out = capsys.readouterr().out
    assert code == 0
    assert "8 tests, 8 extracted, 0 failed, 0 pending" in out
    assert (tmp_path / "c" / "results.parquet").is_file() and (tmp_path / "c" / "results.csv").is_file()


# ---- determinism ------------------------------------------------------------------------------
def test_two_workers_give_the_same_results(inputs, reference, tmp_path):
    run = run_campaign(tmp_path / "two", coupling=inputs["coupling"], doe=inputs["doe"], workers=2, **SETTINGS)
    assert run.executor == "2 local worker processes"
    pd.testing.assert_frame_equal(run.results, reference.results, check_exact=True)
    # the summary's modules were imported on a thread while the workers ran; it ended with the run
    # (a thread alive at the next pool's fork would leave the child holding its import locks)
    import threading

    assert not [t for t in threading.enumerate() if t.name == "droptower-warm-summary"]
    assert (tmp_path / "two" / "summary.csv").is_file()


def test_dask_cluster_gives_the_same_results(inputs, reference, tmp_path):
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=False, dashboard_address=None) as cluster:
        run = run_campaign(tmp_path / "dask", coupling=inputs["coupling"], doe=inputs["doe"],
                           scheduler=cluster.scheduler_address, **SETTINGS)
    assert run.executor.startswith("Dask scheduler")
    pd.testing.assert_frame_equal(run.results, reference.results, check_exact=True)


# ---- resume -----------------------------------------------------------------------------------
def test_interrupted_after_a_chunk_and_resumed(inputs, reference, tmp_path, capsys):
    out = tmp_path / "resumed"
    first = run_campaign(out, coupling=inputs["coupling"], doe=inputs["doe"], workers=1, max_chunks=1, **SETTINGS)
    assert first.pending == 5 and first.results["test_id"].tolist() == [0, 1, 2]
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["summary"] == {"n_tests": 8, "done": 3, "failed": 0, "pending": 5}
    finished = _snapshot(out / "records") | _snapshot(out / "logs")

    code = _cli(inputs, out, "--resume", "--workers", "2")
    assert code == 0
    assert "(5 run now" in capsys.readouterr().out
    summary = pd.read_csv(out / "summary.csv")  # per condition: 2 heights x 2 preloads, 2 repeats each
    assert len(summary) == 4 and (summary["n_tests"] == 2).all()
    assert_drawn(out / "fig11_preload_effect.png", panels=2)  # stiffness and damping ratio
    after = _snapshot(out / "records") | _snapshot(out / "logs")
    assert all(after[name] == finished[name] for name in finished)  # never rewritten
    pd.testing.assert_frame_equal(pd.read_parquet(out / "results.parquet"), reference.results, check_exact=True)


def test_chunk_interrupted_midway_is_completed_bit_for_bit(inputs, reference, tmp_path):
    """A kill inside chunk [3-5]: test 3 finished, test 4's log written but not its record,
    test 5 not started. Resume redoes only 4 and 5, each in its original batch."""
    out = tmp_path / "midway"
    shutil.copytree(reference.root, out)
    for name in ("records/test_00004.json", "records/test_00005.json", "logs/test_00005.parquet",
                 "results.parquet", "results.csv"):
        (out / name).unlink()
    kept = _snapshot(out / "records") | _snapshot(out / "logs")
    kept.pop("test_00004.parquet")
    run = run_campaign(out, coupling=inputs["coupling"], doe=inputs["doe"], workers=1, resume=True, progress=False)
    assert run.ran_tests == 2
    after = _snapshot(out / "records") | _snapshot(out / "logs")
    assert all(after[name] == kept[name] for name in kept)
    pd.testing.assert_frame_equal(run.results, reference.results, check_exact=True)


# ---- a real process, stopped by a signal -----------------------------------------------------------
# The plan above finishes in ~70 ms after its first record (8 tests, ~10 ms each): a window that a
# polling test process and the signal's delivery miss when the machine is loaded. The signal tests
# run a plan of their own, the same conditions with 25 repeats: 100 tests, a chunk each, so 99
# records are still to come when the first lands (~1 s on an idle machine). A load that slows the
# campaign slows its remaining tests alike, so the window is always ~99 tests long, never a race.
SIGNALLED_PLAN = PLAN.replace('name = "small"', 'name = "signalled"', 1).replace("repeats = 2", "repeats = 25", 1)
assert "repeats = 25" in SIGNALLED_PLAN and 'name = "signalled"' in SIGNALLED_PLAN
N_SIGNALLED = 100
SIGNALLED_SETTINGS = dict(duration_s=0.07, chunk_size=1, progress=False)


@pytest.fixture(scope="session")  # kept when worksteal splits this file: a second block reuses it
def signalled(inputs, tmp_path_factory) -> tuple[Path, CampaignRun]:
    """The signal tests' plan, and its campaign run without a stop in this process, first: every
    kernel the campaign calls is then in numba's cache, so a signalled process's first record
    never waits on a compilation (on a cold cache and a loaded machine that took minutes)."""
    doe = inputs["doe"].with_name("signalled.toml")
    doe.write_text(SIGNALLED_PLAN)
    whole = run_campaign(tmp_path_factory.mktemp("signalled") / "campaign", coupling=inputs["coupling"], doe=doe,
                         workers=1, **SIGNALLED_SETTINGS)
    assert whole.pending == 0 and len(whole.results) == N_SIGNALLED
    return doe, whole


# ``python -m droptower.cli.main`` with Ctrl-C raising KeyboardInterrupt, as in a terminal. A process
# that a non-interactive shell starts in the background (``pytest ... &`` in a script, nohup) inherits
# SIGINT *ignored*, and Python then installs no handler: the campaign never saw the signal and ran to
# its end, which failed the Ctrl-C test in every suite run started that way.
AS_FROM_A_TERMINAL = ("import runpy, signal; signal.signal(signal.SIGINT, signal.default_int_handler); "
                      "signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT}); "
                      "runpy.run_module('droptower.cli.main', run_name='__main__', alter_sys=True)")


def _signal_after_the_first_record(inputs, doe: Path, out: Path, sig: int) -> tuple[subprocess.Popen, str, int]:
    """Start ``droptower campaign`` (one worker, a chunk a test) in a fresh interpreter, send
    ``sig`` as soon as its first record is on disk; (the ended process, its stderr, the records)."""
    cmd = [sys.executable, "-c", AS_FROM_A_TERMINAL, "campaign", "--coupling", str(inputs["coupling"]),
           "--doe", str(doe), "--out", str(out), "--duration-s", str(SIGNALLED_SETTINGS["duration_s"]),
           "--chunk-size", str(SIGNALLED_SETTINGS["chunk_size"]), "--workers", "1"]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 600  # a hung process's limit, not a timing: it starts in seconds
        while not list((out / "records").glob("*.json")) and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.005)
        at_signal = len(list((out / "records").glob("*.json")))
        status = Path(f"/proc/{proc.pid}/status")  # the child's signal masks, should it miss the signal (Linux)
        masks = " ".join(line for line in (status.read_text().splitlines() if status.exists() else [])
                         if line.startswith(("SigBlk", "SigIgn", "SigCgt")))
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=600)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    done = len(list((out / "records").glob("*.json")))
    assert 1 <= done < N_SIGNALLED, (f"{at_signal} of {N_SIGNALLED} records when the signal was sent, {done} when "
                                     f"the process ended; its signal masks then: {masks}; stderr: {err[-500:]}")
    return proc, err, done


@pytest.mark.slow
def test_killed_campaign_resumes_to_the_same_results(inputs, signalled, tmp_path):
    """SIGKILL a running ``droptower campaign`` as soon as its first test is finished: every
    record and log under a final name is whole, and the resume runs exactly the rest, to the
    results of the campaign run without a stop."""
    signalled_doe, whole = signalled
    out = tmp_path / "killed"
    proc, _, done = _signal_after_the_first_record(inputs, signalled_doe, out, signal.SIGKILL)
    assert proc.returncode == -signal.SIGKILL
    for path in (out / "records").glob("*.json"):  # nothing half-written under a final name
        assert json.loads(path.read_text())["status"] == "done"
    for path in (out / "logs").glob("*.parquet"):
        assert read_any(path).channels["angle_rad"].values.size > 0
    run = run_campaign(out, coupling=inputs["coupling"], doe=signalled_doe, resume=True, workers=1, progress=False)
    assert run.ran_tests == N_SIGNALLED - done
    pd.testing.assert_frame_equal(run.results, whole.results, check_exact=True)


@pytest.mark.slow
def test_ctrl_c_says_what_is_kept_and_how_to_resume(inputs, signalled, tmp_path):
    """SIGINT (Ctrl-C) once the first test is finished: exit 130, the count of finished tests
    is the count of records on disk, and the resume runs exactly the rest."""
    out = tmp_path / "interrupted"
    proc, err, done = _signal_after_the_first_record(inputs, signalled[0], out, signal.SIGINT)
    assert proc.returncode == 130 and "Traceback" not in err
    assert f"interrupted; {done} test(s) of the campaign are finished and kept" in err and "--resume" in err
    run = run_campaign(out, resume=True, workers=1, progress=False)  # inputs from the manifest
    assert run.ran_tests == N_SIGNALLED - done and run.pending == 0


def test_failed_extractions_are_listed_final_and_not_redone(inputs, tmp_path, capsys):
    out = tmp_path / "short"
    args = ["campaign", "--coupling", str(inputs["coupling"]), "--doe", str(inputs["doe"]), "--out", str(out),
            "--duration-s", "0.005", "--chunk-size", "4", "--workers", "1"]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "8 of 8 test(s) failed" in err and "test 7: " in err and "3/4 of the oscillation period" in err
    table = pd.read_parquet(out / "results.parquet")
    assert (table["status"] == "failed").all() and table["error"].str.contains("oscillation period").all()
    assert not table["error"].str.contains(str(tmp_path)).any()  # the same text in any folder
    assert all((out / f).is_file() for f in table["log_file"])  # the logs are there to look at
    run = run_campaign(out, coupling=inputs["coupling"], doe=inputs["doe"], resume=True, progress=False)
    assert run.ran_tests == 0 and len(run.failed) == 8


def test_failed_simulations_are_recorded_with_their_reason(inputs, tmp_path, capsys):
    """A coupling without static stiffness cannot hold the plan's 500 N*m preload: the chunks'
    tests fail with the rig's reason, the campaign goes on and exits 2."""
    dashpot = tmp_path / "dashpot.toml"
    dashpot.write_text('name = "dashpot"\n[[element]]\nkind = "dashpot"\ndamping = 8.0\n')
    out = tmp_path / "soft"
    code = main(["campaign", "--coupling", str(dashpot), "--doe", str(inputs["doe"]), "--out", str(out),
                 "--duration-s", "0.07", "--chunk-size", "3", "--workers", "1"])
    assert code == 2
    assert "cannot hold the preload" in capsys.readouterr().err
    table = pd.read_parquet(out / "results.parquet")
    assert (table["status"] == "failed").all() and table["error"].str.startswith("simulation: ").all()
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["summary"]["failed"] == 8 and manifest["tests"][0]["log_file"] is None


# ---- bad input: one line, exit 2, nothing touched -----------------------------------------------
def test_folder_of_another_campaign_is_not_touched(inputs, reference, tmp_path, capsys):
    out = tmp_path / "other"
    shutil.copytree(reference.root, out)
    before = _snapshot(out)
    assert _cli(inputs, out, "--resume", coupling="stiffer") == 2
    line = _one_line_error(capsys.readouterr().err)
    assert "holds a different campaign (its coupling differ" in line and "choose another --out" in line
    assert _cli(inputs, out, "--resume", "--chunk-size", "4") == 2
    assert "chunk_size (3 in the folder, 4 given)" in _one_line_error(capsys.readouterr().err)
    assert _cli(inputs, out) == 2  # the same campaign, without --resume
    assert "add --resume to continue it" in _one_line_error(capsys.readouterr().err)
    assert _snapshot(out) == before


def test_non_empty_folder_without_a_campaign_is_refused(inputs, tmp_path, capsys):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("my notes")
    for extra in ([], ["--resume"]):
        assert _cli(inputs, out, *extra) == 2
        assert "is not empty and holds no campaign" in _one_line_error(capsys.readouterr().err)
    assert [p.name for p in out.iterdir()] == ["notes.txt"]


def test_scheduler_that_does_not_answer(inputs, tmp_path, capsys):
    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    out = tmp_path / "dask"
    code = _cli(inputs, out, "--scheduler", f"tcp://127.0.0.1:{port}", "--scheduler-timeout-s", "0.2")
    assert code == 2
    line = _one_line_error(capsys.readouterr().err)
    assert f"--scheduler: the Dask scheduler at tcp://127.0.0.1:{port} does not answer within 0.2 s" in line
    assert not out.exists()


def test_workers_and_scheduler_together_are_refused(inputs, tmp_path, capsys):
    assert _cli(inputs, tmp_path / "x", "--workers", "2", "--scheduler", "tcp://127.0.0.1:1") == 2
    assert "not both" in _one_line_error(capsys.readouterr().err)
    assert _cli(inputs, tmp_path / "y", "--workers", "0") == 2
    assert "--workers: must be at least 1" in _one_line_error(capsys.readouterr().err)


def test_resume_from_the_manifest_alone(inputs, reference, tmp_path, capsys):
    """A custom plan and coupling, interrupted; the inputs are then moved away. ``--resume``
    with nothing but the folder restores them from the manifest and says what it will run."""
    moved = tmp_path / "inputs"
    moved.mkdir()
    coupling, doe = shutil.copy(inputs["coupling"], moved), shutil.copy(inputs["doe"], moved)
    out = tmp_path / "alone"
    run_campaign(out, coupling=coupling, doe=doe, workers=1, max_chunks=1, **SETTINGS)
    shutil.rmtree(moved)
    code = main(["campaign", "--out", str(out), "--resume", "--workers", "1"])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    assert f"resuming {out}: 3 of 8 tests finished, 5 to run" in captured.err
    assert "8 tests, 8 extracted, 0 failed, 0 pending (5 run now" in captured.out
    pd.testing.assert_frame_equal(pd.read_parquet(out / "results.parquet"), reference.results, check_exact=True)
    assert sorted(p.name for p in (out / "inputs").iterdir()) == ["linear.toml", "small.toml"]


def test_holds_a_campaign_counts_the_records_on_disk(inputs, reference, tmp_path, capsys):
    """After a kill the manifest lags behind the records: the message counts the records."""
    out = tmp_path / "lagging"
    shutil.copytree(reference.root, out)
    manifest = json.loads((out / "manifest.json").read_text())
    for test in manifest["tests"][3:]:
        test["status"] = "pending"
    (out / "manifest.json").write_text(json.dumps(manifest))
    assert _cli(inputs, out) == 2
    assert "(8 of 8 tests finished)" in capsys.readouterr().err


def test_the_library_writes_the_per_condition_summary_and_names_every_output(reference):
    """``run_campaign`` itself writes what the command reports (the command only prints
    ``run.outputs``): the results tables, the logs and the per-condition summary, whose rows
    are the plan's conditions with their usable tests counted."""
    from droptower.maps.summary import condition_summary

    written = {path.name: what for path, what in reference.outputs}
    assert {"results.parquet", "results.csv", "logs", "summary.csv"} <= set(written)
    assert all(path.exists() for path, _ in reference.outputs)
    summary, expected = pd.read_csv(reference.root / "summary.csv"), condition_summary(reference.results)
    assert len(summary) == len(expected) > 0
    assert summary["n_tests"].tolist() == expected["n_tests"].tolist()
