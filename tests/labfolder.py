"""Test helper: a lab's own folder of drop-test logs, as a lab exports it (not as droptower writes
logs). The generator is the package's :mod:`droptower.campaign.lab_export` (public, documented:
"write a virtual campaign as a lab's export, to rehearse the evaluation"); this module re-exports
it under the names the tests use, and runs commands on such a folder in this process
(:func:`droptower`: the session fixtures of tests/conftest.py that several files read)."""
from __future__ import annotations

import contextlib
import io
from dataclasses import dataclass

from droptower.campaign.lab_export import (FIXTURES, GERMAN, HEIGHTS_MM, IMPERIAL, LAB_RIG_TOML, MASSES, REPEATS,
                                           LabDialect, LabFolder, _write_csv, _write_sheet, write_lab_folder)

Dialect = LabDialect  # the name the tests knew it by

__all__ = ["Dialect", "FIXTURES", "GERMAN", "HEIGHTS_MM", "IMPERIAL", "LAB_RIG_TOML", "LabDialect", "LabFolder", "MASSES",
           "REPEATS", "Step", "droptower", "write_lab_folder", "_write_csv", "_write_sheet"]


@dataclass
class Step:
    """One command: its exit code, stdout and stderr."""

    code: int
    out: str
    err: str


def droptower(*args: object) -> Step:
    """``droptower ARGS`` in this process, its output captured (not by ``capsys``: session
    fixtures run it too)."""
    from droptower.cli.main import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main([str(a) for a in args])
    return Step(code, out.getvalue(), err.getvalue())
