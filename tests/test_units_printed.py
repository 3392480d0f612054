"""One way to print each unit: a torque prints as N*m (or N·m), never "nm" (nanometres), in
every message string of the package and in the rendered verdict."""
from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

import droptower
from droptower.identify.verdict import judge
from droptower.units import printed_unit

PACKAGE = Path(droptower.__file__).parent
#: "nm", "Nm", "nms" as a word of printed text (not the unit token of a field name: torque_nm)
BARE_NM = re.compile(r"(?<![\w.-])(nm|Nm|nms)(?![\w])")
#: string constants that may hold such a word, with why
ALLOWED = {
    ("units.py", ""): "the unit spellings the parser reads (a log's 'Nm' header) and the field-name tokens",
    ("cli/validate_cmd.py", "[Nm/°]"): "the German column header of a servo table the command reads",
    ("rig/scene.py", "1 nm"): "a length: the physics engine's collision slop is one nanometre",
    ("campaign/lab_export.py", "Moment [Nm]"): "the German lab dialect's torque header, written as such labs write it",
}
#: whole-string constants that are unit tokens of field names (torque_nm), not printed text
TOKENS = {"nm", "nms"}


def _hits() -> list[str]:
    hits = []
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE).as_posix()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if not (isinstance(node, ast.Constant) and isinstance(node.value, str)) or node.value in TOKENS:
                continue
            for m in BARE_NM.finditer(node.value):
                text = node.value[max(0, m.start() - 30):m.end() + 30]
                if not any(rel == f and a in text for f, a in ALLOWED):
                    hits.append(f"{rel}:{node.lineno}: {text!r}")
    return hits


def test_no_message_prints_nm_for_a_torque():
    assert _hits() == []


def test_the_scan_finds_a_bare_nm():  # the scan itself can fail
    assert BARE_NM.search("noise allowance 0.318 nm") and BARE_NM.search("T = 5 Nm")
    assert not BARE_NM.search("torque_nm, noise_allowance_nm, N*m, N·m")


@pytest.mark.parametrize("token, printed", [("nm", "N*m"), ("rad", "rad"), ("n", "N"), ("nms", "N*m*s"),
                                            ("nm_per_rad", "N*m/rad"), ("n_per_m", "N/m"), ("nm_per_deg", "N*m/deg")])
def test_printed_unit(token, printed):
    assert printed_unit(token) == printed


@pytest.mark.parametrize("token, printed", [("nm", "N*m"), ("n", "N"), ("rad", "rad")])
def test_verdict_text_prints_the_unit(token, printed):
    text = judge(1.0, 0.318, token, []).text()
    assert f"0.318 {printed};" in text and not BARE_NM.search(text)
    # the JSON keeps the field-name token
    assert f"noise_allowance_{token}" in judge(1.0, 0.318, token, []).to_dict()
