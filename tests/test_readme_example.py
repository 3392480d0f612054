"""The README as a reader meets it: its Python example runs as written and prints what it says,
it stays short (at most 200 lines), its first two commands are the ones `.ci/run` runs, and the
licence and changelog it links to are there."""
from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text(encoding="utf-8")


def _python_blocks(text: str) -> list[str]:
    return re.findall(r"^```python\n(.*?)^```$", text, re.S | re.M)


@pytest.mark.slow
def test_the_python_example_runs_as_written(tmp_path):
    (example,) = _python_blocks(README)
    assert len(example.strip().splitlines()) <= 12, "the README's example is meant to be about ten lines"
    env = {**os.environ, "MPLBACKEND": "Agg"}
    done = subprocess.run([sys.executable, "-c", example], cwd=tmp_path, env=env, capture_output=True, text=True,
                          timeout=600)
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "drop.parquet").is_file()
    first, header, row = done.stdout.strip().splitlines()
    # one drop test of the reference coupling: a damped oscillation of a few tens of Hz whose
    # stiffness the servo bench at the same amplitude and frequency confirms (the drop tower's
    # c = J(w^2 + delta^2) and the bench's K' agree within the map-vs-servo deviation stated in
    # docs/study.md, well under 10 %)
    found = re.fullmatch(r"([\d.]+) Hz, c = (\d+) N·m/rad, d = ([\d.]+)", first)
    assert found, first
    frequency_hz, stiffness_nm_per_rad, damping_ratio = map(float, found.groups())
    assert 10 < frequency_hz < 100 and damping_ratio > 0
    assert header.split() == ["storage_stiffness_nm_per_deg", "loss_factor"]
    storage_nm_per_deg, loss_factor = map(float, row.split()[1:])
    assert abs(storage_nm_per_deg * 180 / 3.141592653589793 / stiffness_nm_per_rad - 1) < 0.1
    assert 0 < loss_factor < 1


def test_the_readme_is_short_and_starts_with_the_two_commands():
    lines = README.splitlines()
    assert len(lines) <= 200, f"README.md has {len(lines)} lines; move the rest into docs/"
    commands = [line for line in lines if line.startswith("python3 -m venv")]
    assert commands[:2] == [
        "python3 -m venv .venv && .venv/bin/pip install . && .venv/bin/droptower campaign --out campaign && "
        ".venv/bin/droptower map campaign --plot campaign/map",
        'python3 -m venv .venv && .venv/bin/pip install --quiet ".[test]" && .venv/bin/python -m pytest -n 2 -q',
    ]
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8")
    assert commands[1] in ci.splitlines(), ".ci/run must run the README's test command verbatim"
    assert 'pip install ".[docs]"' in README and "mkdocs build --strict" in README
    assert "mkdocs build --strict" in ci


def test_every_link_of_the_readme_leads_to_a_file():
    targets = re.findall(r"\]\(([^)#]+)(?:#[^)]*)?\)", README)
    missing = [t for t in targets if not t.startswith("http") and not (ROOT / t).exists()]
    assert targets and not missing, missing


def test_licence_and_changelog():
    licence = (ROOT / "LICENSE").read_text(encoding="utf-8")
    assert licence.startswith("MIT License") and "the droptower developers" in licence
    assert 'license = { text = "MIT" }' in (ROOT / "pyproject.toml").read_text(encoding="utf-8")
    changelog = (ROOT / "CHANGELOG.md").read_text(encoding="utf-8")
    assert changelog.startswith("# Changelog") and "keepachangelog.com" in changelog
    versions = re.findall(r"^## \[([^\]]+)\]", changelog, re.M)
    assert versions[:1] == ["Unreleased"] and "0.1.0" in versions
