"""The default sample rates are named once (droptower.rates): no other number restates them, and
the figures the documentation quotes are theirs."""
from __future__ import annotations

import ast
import inspect
import re
import tokenize
from pathlib import Path

from click.testing import CliRunner

from droptower.cli.main import cli
from droptower.fmu.build import DEFAULT_STEP_S
from droptower.rates import RIG_SAMPLE_RATE_HZ, SERVO_SAMPLE_RATE_HZ
from droptower.rig import load_rig
from droptower.servo import run_grid

REPO = Path(__file__).resolve().parents[1]
RATES = {RIG_SAMPLE_RATE_HZ: "RIG_SAMPLE_RATE_HZ", SERVO_SAMPLE_RATE_HZ: "SERVO_SAMPLE_RATE_HZ"}
#: a figure of the rig's or the servo bench's rate in prose: 38.4 kHz, 38 400 Hz, 1/38400 s, 2048 Hz
FIGURE = re.compile(r"\b(38(?:\.\d+)?)\s*kHz|\b(38[\u00a0\u202f _,]?\d00|2[\u00a0\u202f _,]?048)\b")
#: quotes of the paper's hardware, not of the package's defaults
QUOTES = ("sampling up to 38 kHz", "maximum sampling rate of 38 kHz")


def _figures(text: str) -> list[float]:
    for quote in QUOTES:
        text = text.replace(quote, "")
    found = []
    for m in FIGURE.finditer(text):
        found.append(float(m.group(1)) * 1e3 if m.group(1) else float(re.sub(r"\D", "", m.group(2))))
    return found


def test_the_figure_scan_reads_every_form():
    assert _figures("at 38.4 kHz, 1/38 400 s, 38400 Hz, 38_400, 2048 Hz, 2 048 Hz; up to 38 kHz, 38 200 Hz") == [
        38400.0, 38400.0, 38400.0, 38400.0, 2048.0, 2048.0, 38000.0, 38200.0]
    assert _figures("a 30 Hz sine, 450 tests, 153.6 kHz, 4096 steps, 2020, p. 33795") == []


def test_the_documentation_quotes_the_named_rates():
    pages = [REPO / "README.md", *sorted((REPO / "docs").rglob("*.md"))]
    wrong = [(page.relative_to(REPO).as_posix(), figure) for page in pages
             for figure in _figures(page.read_text(encoding="utf-8")) if figure not in RATES]
    assert not wrong, f"figures that are not droptower.rates' {sorted(RATES)} Hz: {wrong}"


def test_no_other_number_restates_a_rate():
    # numbers in code (not prose): a default written as 38400.0 or 2048.0 instead of the name
    found = []
    for root in ("droptower", "benchmarks", "analysis"):
        for path in sorted((REPO / root).rglob("*.py")):
            if path.name == "rates.py":
                continue
            with tokenize.open(path) as f:
                for tok in tokenize.generate_tokens(f.readline):
                    if tok.type == tokenize.NUMBER:
                        value = ast.literal_eval(tok.string)
                        if value in RATES and tok.line.split("=")[0].strip() != "TARGET_MB":
                            found.append(f"{path.relative_to(REPO)}:{tok.start[0]}: {tok.line.strip()}")
    assert not found, "\n".join(found)


def test_the_defaults_are_the_named_rates():
    assert load_rig("rapp2022").sensors.sample_rate_hz == RIG_SAMPLE_RATE_HZ
    assert DEFAULT_STEP_S == 1.0 / RIG_SAMPLE_RATE_HZ
    defaults = {name: p.default for name, p in inspect.signature(run_grid).parameters.items()}
    assert defaults["sample_rate_hz"] == SERVO_SAMPLE_RATE_HZ and defaults["simulation_rate_hz"] == RIG_SAMPLE_RATE_HZ
    servo_help = CliRunner().invoke(cli, ["servo", "--help"], terminal_width=200).output
    assert f"default: {SERVO_SAMPLE_RATE_HZ}" in servo_help and f"default: {RIG_SAMPLE_RATE_HZ}" in servo_help
