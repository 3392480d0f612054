"""The installed console script, run as a user runs it: in a fresh interpreter, not in-process.

In-process tests share pytest's already-imported modules and so miss import errors of the
command itself (``importlib.util`` was used without being imported and ``droptower --help``
crashed on every non-editable install).
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from droptower.cli.main import COMMANDS


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


@pytest.mark.parametrize("name", list(COMMANDS))
def test_every_subcommand_help(name):
    proc = _run(name, "--help")
    assert proc.returncode == 0, proc.stderr
    assert "Usage:" in proc.stdout and "Traceback" not in proc.stderr
