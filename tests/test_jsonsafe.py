"""The one JSON clean-up (droptower.jsonsafe.json_safe): strict JSON from any nesting of numpy
values, NaN and infinities as null; and no other copy of it in the package."""
from __future__ import annotations

import datetime as dt
import json
import math
import re
from pathlib import Path, PurePosixPath

import numpy as np
from hypothesis import given, seed, settings
from hypothesis import strategies as st

from droptower.jsonsafe import json_safe

REPO = Path(__file__).resolve().parents[1]

FLOATS = st.floats(allow_nan=True, allow_infinity=True, width=64)
SCALARS = st.one_of(
    st.none(), st.booleans(), st.integers(-2**62, 2**62), FLOATS, st.text(max_size=5),
    FLOATS.map(np.float64), st.floats(width=32).map(np.float32), st.integers(-2**31, 2**31 - 1).map(np.int32),
    st.integers(-2**62, 2**62).map(np.int64), st.booleans().map(np.bool_),
    st.lists(FLOATS, max_size=4).map(lambda v: np.array(v, float)),
    st.lists(st.integers(-9, 9), max_size=4).map(lambda v: np.array(v, np.int64).reshape(-1, 1)),
    st.text(max_size=4).map(PurePosixPath))
KEYS = st.one_of(st.text(alphabet="abc", max_size=3), st.integers(-5, 5), st.integers(-5, 5).map(np.int64))
NESTED = st.recursive(SCALARS, lambda inner: st.one_of(
    st.lists(inner, max_size=3), st.lists(inner, max_size=3).map(tuple), st.dictionaries(KEYS, inner, max_size=3)),
    max_leaves=12)


def _same(original, clean) -> bool:
    """``clean`` holds what ``original`` held: finite numbers equal, non-finite ones None."""
    if isinstance(original, np.ndarray):
        original = original.tolist()
    if isinstance(original, np.generic):
        original = original.item()
    if isinstance(original, dict):
        return isinstance(clean, dict) and len(clean) == len(original) and all(
            isinstance(k, str) for k in clean) and all(_same(v, clean[k]) for v, k in zip(original.values(), clean))
    if isinstance(original, (list, tuple)):
        return isinstance(clean, list) and len(clean) == len(original) and all(map(_same, original, clean))
    if isinstance(original, float):
        return clean is None if not math.isfinite(original) else (type(clean) is float and clean == original)
    if isinstance(original, PurePosixPath):
        return clean == str(original)
    return type(clean) is type(original) and clean == original


@seed(29)
@settings(max_examples=150, deadline=None)
@given(NESTED)
def test_any_nesting_becomes_strict_json_that_holds_the_same_values(value):
    clean = json_safe(value)
    text = json.dumps(clean, allow_nan=False)  # strict: raises on NaN, infinity, numpy types
    assert json.loads(text) == clean  # plain data: reads back as written
    assert _same(value, clean)
    assert json_safe(clean) == clean  # idempotent


def test_the_policy_case_by_case():
    assert json_safe({"a": float("nan"), "b": -np.inf, "c": np.float32(0.5), 1: np.int64(3), None: np.bool_(False), 0.5: 1,
                      np.int64(2): (1, 2), "p": Path("x") / "y.csv", "d": dt.date(2026, 11, 27),
                      "e": np.array([[1.0, np.nan]])}) == {
        "a": None, "b": None, "c": 0.5, "1": 3, "null": False, "0.5": 1, "2": [1, 2], "p": str(Path("x") / "y.csv"),
        "d": "2026-11-27", "e": [[1.0, None]]}
    assert type(json_safe(np.float64(2.5))) is float and type(json_safe(np.int8(-3))) is int
    assert json_safe(np.float64(np.nan)) is None and json_safe(np.array(7)) == 7
    assert json_safe(complex(1, 2)) == "(1+2j)"  # anything else: its text


def test_no_other_json_clean_up_is_left_in_the_package():
    # the hand-written forms the copies took: NaN to None by isfinite, numpy scalars by .item()
    # inside a JSON default hook, the str default of json.dumps
    forms = re.compile(r"isfinite\([^)]*\) else None|else None for [^\n]* in .*isfinite|default=str"
                       r"|def (_?json_safe|strict_json|_clean|_finite|_numbers)\(")
    exempt = {
        # the campaign's identity hash: canonical text of the spec, kept byte for byte (stored
        # campaigns are recognised by it), not an output
        "droptower/campaign/spec.py",
        "droptower/jsonsafe.py",
    }
    found = [f"{path.relative_to(REPO)}:{n}: {line.strip()}"
             for path in sorted((REPO / "droptower").rglob("*.py")) if path.relative_to(REPO).as_posix() not in exempt
             for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1) if forms.search(line)]
    assert not found, "\n".join(found)
