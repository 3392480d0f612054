"""The library speaks Python, the command line speaks flags: no string the library's code
builds (messages, defaults) and no docstring or comment outside ``droptower/cli/`` (what a
Python user reads in ``help()``), and no file the library writes (a coupling's or a plan's
description), names a command-line flag, not even in a ``droptower COMMAND --flag`` example: a
command is named without its flags, and the CLI adds its own. A library message
names the Python parameter or config key in backticks; the command line reports it with its
flag (``droptower/cli/flags.py``), so every such name must have one there."""
from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

from droptower.cli.flags import FLAGS, cli_message, cli_text
from droptower.errors import DroptowerError

ROOT = Path(__file__).resolve().parents[1]
LIBRARY = [p for p in sorted((ROOT / "droptower").rglob("*.py")) if "cli" not in p.relative_to(ROOT).parts]
FLAG = re.compile(r"(?<![\w`-])--[a-z][a-z0-9-]*")
NAMED = re.compile(r"`([a-z_/]+)(?:=[^`]*)?`")


def _strings(path: Path) -> list[tuple[int, str]]:
    """Every string constant of ``path`` with its line, docstrings left out, f-strings' literal parts in."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    docstrings = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and node.body:
            first = node.body[0]
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant):
                docstrings.add(id(first.value))
    return [(node.lineno, node.value) for node in ast.walk(tree)
            if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docstrings]


def test_the_scan_sees_the_library():
    assert len(LIBRARY) > 50 and not any("cli" in p.parts for p in LIBRARY)
    found = [text for p in LIBRARY for _, text in _strings(p)]
    assert any("no rotating inertia" in text for text in found)


@pytest.mark.parametrize("path", LIBRARY, ids=lambda p: str(p.relative_to(ROOT)))
def test_no_command_line_flag_in_library_strings(path):
    bad = []
    for line, text in _strings(path):
        if FLAG.search(text):
            bad.append(f"{path.relative_to(ROOT)}:{line}: {text.strip()[:100]}")
    assert not bad, ("the library names a command-line flag; name the Python parameter in backticks (the CLI "
                     "turns it into the flag, droptower/cli/flags.py):\n" + "\n".join(bad))


@pytest.mark.parametrize("path", LIBRARY, ids=lambda p: str(p.relative_to(ROOT)))
def test_no_command_line_flag_in_library_docs(path):
    bad = [f"{path.relative_to(ROOT)}:{i}: {line.strip()[:100]}"
           for i, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1)
           if FLAG.search(line)]
    assert not bad, ("the library's docstrings or comments give a command-line flag to a Python reader; name the "
                     "Python parameter (the CLI's help names its flags):\n" + "\n".join(bad))


def test_every_name_the_library_cites_has_a_flag():
    cited = {(name, f"{path.relative_to(ROOT)}:{line}") for path in LIBRARY for line, text in _strings(path)
             for name in NAMED.findall(text)}
    missing = sorted(where + ": " + name for name, where in cited if name not in FLAGS)
    assert cited and not missing, "names in library messages without a flag in droptower/cli/flags.py:\n" + "\n".join(missing)


def test_the_command_line_says_flags():
    assert cli_text("give `inertia_kgm2` or `rig`") == "give --inertia-kgm2 or --rig"
    assert cli_text("name it with `roles={'angle': 'NAME[:UNIT]'}`") == "name it with --channel angle=NAME[:UNIT]"
    assert cli_text("`max_tests=8`: 2 repeat(s)") == "--max-tests 8: 2 repeat(s)"
    assert cli_text("`drops='0'`: drops are numbered from 1") == "--drops '0': drops are numbered from 1"
    assert cli_text("run `droptower extract --out` and `unknown`") == "run `droptower extract --out` and `unknown`"
    error = DroptowerError("must be at least 1, got 0", where="workers", file="plan.toml")
    assert error.message == "plan.toml: workers: must be at least 1, got 0"  # the Python user's words
    assert cli_message(DroptowerError("must be > 0, got inf", where="workers")) == "--workers: must be > 0, got inf"
    in_a_file = DroptowerError("must be > 0, got inf", file="log.csv", where="lever_length_m")  # a log's field
    assert cli_message(in_a_file) == "log.csv: lever_length_m: must be > 0, got inf"


def test_the_command_line_reports_the_library_error_with_its_flags(tmp_path, capsys):
    """A real case end to end: a log without the lever inertia, extracted by the library (the
    Python names) and by the command (its flags)."""
    import numpy as np
    import pandas as pd

    from droptower.cli.main import main
    from droptower.extract import Settings, extract_file

    t = np.arange(2000) / 10_000
    log = tmp_path / "drop.csv"
    pd.DataFrame({"time_s": t, "angle_rad": 0.01 * np.exp(-20 * t) * np.sin(2 * np.pi * 30 * t),
                  "torque_nm": 100 * np.exp(-20 * t) * np.sin(2 * np.pi * 30 * t)}).to_csv(log, index=False)
    with pytest.raises(DroptowerError, match="give `inertia_kgm2`"):
        extract_file(log, Settings())
    assert main(["extract", str(log)]) == 2
    err = capsys.readouterr().err
    assert "give --inertia-kgm2" in err and "`" not in err, err
