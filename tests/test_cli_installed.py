"""The installed console script, run as a user runs it: in a fresh interpreter, not in-process.

In-process tests share pytest's already-imported modules and so miss import errors of the
command itself (``importlib.util`` was used without being imported and ``droptower --help``
crashed on every non-editable install).
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from droptower.cli.main import COMMANDS, main

#: the same tests' map fitted once per process by this module's commands and calls (tests/conftest.py)
pytestmark = pytest.mark.usefixtures("shared_map_fits")


def _console_script() -> list[str]:
    """The ``droptower`` script beside this interpreter (a venv's bin/), else ``python -m``."""
    script = Path(sys.executable).with_name("droptower")
    if script.is_file():
        return [str(script)]
    found = shutil.which("droptower")
    return [found] if found else [sys.executable, "-m", "droptower"]


def _run(*args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "MPLBACKEND": "Agg"}
    return subprocess.run([*_console_script(), *args], capture_output=True, text=True, timeout=300, env=env)


@pytest.mark.parametrize("args", [["--help"], []])
def test_top_level_help_lists_every_command(args):
    proc = _run(*args)
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stderr
    for name in COMMANDS:
        assert name in proc.stdout


#: Commands that run for real as installed below (or, extract, in
#: test_hardening.py::test_installed_extract_ends_with_its_own_exit_code, and map, on a lab's
#: results table, in test_lab_folder_e2e.py::test_the_results_table_reads_back_in_a_fresh_process):
#: a fresh interpreter imports each one's module there, so its help is read in this process; the
#: others' help is their one run as installed.
RUN_AS_INSTALLED = {"servo", "simulate", "channels", "extract", "plan", "campaign", "report", "map", "validate",
                    "identify", "compare-models"}


@pytest.mark.parametrize("name", list(COMMANDS))
def test_every_subcommand_help_has_examples_and_quiet(name, capsys):
    if name in RUN_AS_INSTALLED:
        code, out, err = main([name, "--help"]), *capsys.readouterr()
    else:
        proc = _run(name, "--help")
        code, out, err = proc.returncode, proc.stdout, proc.stderr
    assert code == 0, err
    assert "Usage:" in out and "Traceback" not in err
    assert "Examples:" in out and "--quiet" in out


def test_every_command_whose_help_is_read_in_process_runs_as_installed():
    """The in-process help above stands only where a real run as installed imports the command."""
    import inspect
    import re

    import test_hardening
    import test_lab_folder_e2e

    runs = (Path(__file__).read_text() + inspect.getsource(test_hardening.test_installed_extract_ends_with_its_own_exit_code)
            + inspect.getsource(test_lab_folder_e2e.test_the_results_table_reads_back_in_a_fresh_process))
    assert RUN_AS_INSTALLED <= set(COMMANDS)
    for name in RUN_AS_INSTALLED:
        assert re.search(rf'_(ok|run)\("{name}"', runs), name


# ---- one real run of every command, as installed ------------------------------------------------
LINEAR = 'name = "linear"\n[[element]]\nkind = "spring"\nstiffness = 14000.0\n' \
         '[[element]]\nkind = "dashpot"\ndamping = 8.0\n'
PLAN = 'name = "two"\nbase_seed = 1\nrepeats = 1\nheights_m = [0.5, 1.0]\npreloads_nm = [0.0]\n' \
       '[[group]]\nname = "case 2"\ninertia_kgm2 = 0.359\ndrop_mass_kg = 2.0\n'


@pytest.fixture(scope="module")
def folder(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("installed")
    (root / "linear.toml").write_text(LINEAR)
    (root / "two.toml").write_text(PLAN)
    return root


def _ok(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    proc = _run(*args) if cwd is None else subprocess.run([*_console_script(), *args], capture_output=True,
                                                          text=True, timeout=300, cwd=cwd,
                                                          env={**os.environ, "MPLBACKEND": "Agg"})
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stderr
    return proc


def test_run_servo():
    rows = json.loads(_ok("servo", "seed000_six_parameter", "--amplitude-deg", "0.5", "--frequency-hz", "10",
                          "--cycles", "1", "--run-in-cycles", "1", "--json").stdout)
    assert len(rows) == 1 and rows[0]["storage_stiffness_nm_per_deg"] > 0


def test_run_simulate_channels_extract(folder, capsys):
    """simulate and channels as installed; extract in this process (the installed extract runs in
    test_hardening.py::test_installed_extract_ends_with_its_own_exit_code, with its exit codes)."""
    log = folder / "t.csv"
    s = json.loads(_ok("simulate", "--coupling", str(folder / "linear.toml"), "--inertia-kgm2", "0.359",
                       "--drop-mass-kg", "2", "--height-m", "0.5", "--duration-s", "0.06", "--out", str(log),
                       "--json").stdout)
    assert s["contacts"] >= 1 and s["energy_balance_error_fraction"] < 0.01
    channels = json.loads(_ok("channels", str(log), "--json").stdout)
    assert {c["name"] for c in channels} >= {"angle_rad", "torque_nm"}
    capsys.readouterr()
    assert main(["extract", str(log), "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    # Kelvin-Voigt coupling: c = J (omega^2 + delta^2) = k (Rapp et al. 2022, eq. 15)
    assert rows[0]["stiffness_nm_per_rad"] == pytest.approx(14000.0, rel=0.01)


@pytest.mark.slow
def test_run_plan_campaign_map_validate(folder):
    plan = json.loads(_ok("plan", "--coupling", str(folder / "linear.toml"), "--doe", str(folder / "two.toml"),
                          "--json").stdout)
    assert len(plan) == 2
    camp = folder / "camp"
    proc = _ok("campaign", "--coupling", str(folder / "linear.toml"), "--doe", str(folder / "two.toml"),
               "--out", str(camp), "--workers", "1", "--duration-s", "0.06", "--quiet")
    assert "2 tests, 2 extracted, 0 failed" in proc.stdout and proc.stderr == ""
    assert len(pd.read_parquet(camp / "results.parquet")) == 2
    assert len(pd.read_csv(camp / "summary.csv")) == 2  # one row per condition
    _ok("report", str(camp))
    assert (camp / "report.html").stat().st_size > 100_000
    map_file = folder / "map.json"  # map's run as installed: test_lab_folder_e2e.py, on a lab's results table
    assert main(["map", "rapp2022_table4", "--out", str(map_file)]) == 0
    servo = folder / "servo.csv"
    pd.DataFrame({"amplitude_deg": [0.5, 1.5], "frequency_hz": [30.0, 30.0],
                  "storage_stiffness_nm_per_deg": [250.0, 200.0], "loss_factor": [0.2, 0.25]}).to_csv(servo, index=False)
    doc = json.loads(_ok("validate", "--map", str(map_file), "--servo-results", str(servo), "--json").stdout)
    assert len(doc["points"]) == 2


def test_run_identify_and_compare_models(folder):
    # a sine on the linear coupling: T = k phi + c dphi/dt, sampled at 2048 Hz
    t = np.arange(4096) / 2048.0
    angle = np.radians(1.0) * np.sin(2 * np.pi * 5 * t)
    torque = 14000.0 * angle + 8.0 * np.gradient(angle, t)
    # a measurement's noise (0.5 %): on a noise-free record any model error is many times the
    # noise and the verdict is "poor fit" (exit 3)
    torque += np.random.default_rng(0).normal(0.0, 0.005 * np.abs(torque).max(), t.size)
    record = folder / "sine.csv"
    pd.DataFrame({"time_s": t, "angle_rad": angle, "torque_nm": torque}).to_csv(record, index=False)
    report = json.loads(_ok("identify", str(record), "--family", "pfeffer", "--json").stdout)
    assert report["family"] == "pfeffer" and report["converged"]
    proc = _ok("compare-models", str(record), "--families", "pfeffer,overlay", "--json")
    assert [r["family"] for r in json.loads(proc.stdout)["ranking"]] == ["pfeffer"]
    assert "skipped" in proc.stderr and "overlay" in proc.stderr
