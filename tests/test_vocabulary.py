"""One vocabulary: one result schema and one text report for servo records and drop tests, one
word for a model family, one name per statistic, ``summary()`` text everywhere, the entry
points at the top level; every name of release 0.1 still works with a DeprecationWarning."""
from __future__ import annotations

import ast
import importlib
import json
import math
import re
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import given, settings, strategies as st

import droptower
from droptower import load_coupling
from droptower.errors import DroptowerError
from droptower.identify.result import (DROPS, RESULT_KEYS, SERVO, SUMMARY_SECTIONS, Identification, Metrics,
                                       Parameters)
from droptower.identify.verdict import judge

ROOT = Path(__file__).resolve().parents[1]
COUPLING = load_coupling("seed000_six_parameter")


def _params() -> Parameters:
    p = Parameters()
    p.add("k1_nm_per_rad", 3000.0, stderr=3.0, min=1.0, max=1e5)
    p.add("tau2_s", 0.2, stderr=0.01, min=0.01, max=0.2)
    p.add("k3_nm_per_rad", 50.0, vary=False)
    return p


def servo_result(**kw) -> Identification:
    """An identification from servo records whose every figure is known."""
    return Identification("zerodim6", _params(), ["tau2_s"], Metrics(0.1, 0.01, 0.2, 100, 10.0), COUPLING, SERVO,
                          holdout_error=Metrics(0.12, 0.012, 0.1, 50, 10.0), wall_s=1.5,
                          verdict=judge(0.1, 0.08, "nm", []), converged=True, evaluations=10, nfev=3, **kw)


def drop_result(**kw) -> Identification:
    """An identification from drop tests whose every figure is known."""
    per_test = [{"file": "a.parquet", "angle_nrmse": 0.01, "rate_source": "impact_force", "inertia_kgm2": 0.1,
                 "amplitude_deg": 1.0, "frequency_hz": 20.0}]
    err = {"tests": 1, "angle_nrmse": 0.01, "angle_nrmse_max": 0.01, "per_test": per_test}
    return Identification("zerodim6", _params(), ["tau2_s"], err, COUPLING, DROPS, wall_s=2.0,
                          verdict=judge(2e-4, 1e-4, "rad", []), converged=True, evaluations=5, nfev=2,
                          tests_used=["a.parquet"], search={"candidates": 64, "local_fits": 3}, **kw)


# ---------------------------------------------------------------------------- one schema
def test_servo_and_drop_identifications_serialise_to_one_schema():
    servo, drops = servo_result().to_dict(), drop_result().to_dict()
    assert list(servo) == list(drops) == list(RESULT_KEYS)
    for doc, data, wall, nrmse in ((servo, SERVO, 1.5, 0.01), (drops, DROPS, 2.0, 0.01)):
        doc = json.loads(json.dumps(doc, allow_nan=False))  # JSON as written: no NaN, no numpy types
        assert doc["family"] == "zerodim6" and doc["data"] == data and doc["wall_s"] == wall
        assert doc["fit_error"]["nrmse"] == nrmse and doc["n_parameters"] == 3
        assert doc["parameters"]["tau2_s"] == {"value": 0.2, "stderr": 0.01, "min": 0.01, "max": 0.2, "vary": True,
                                               "unit": "s", "at_bound": True}
        assert doc["parameters"]["k3_nm_per_rad"]["stderr"] is None and not doc["parameters"]["k3_nm_per_rad"]["vary"]
        assert doc["evaluations"] in (10, 5) and doc["converged"] is True and doc["uncertainty"] is None
    # the verdict: 0.1 / 0.08 and 2e-4 / 1e-4, each noise value named with its unit
    assert servo["error_over_noise"] == pytest.approx(1.25) and servo["noise"] == {
        "noise_floor_nm": 0.08, "noise_allowance_nm": 0.08}
    assert drops["error_over_noise"] == pytest.approx(2.0) and set(drops["noise"]) == {"noise_floor_rad",
                                                                                       "noise_allowance_rad"}
    assert servo["holdout_error"]["nrmse"] == 0.012 and drops["holdout_error"] is None
    assert drops["search"] == {"candidates": 64, "local_fits": 3} and servo["search"] == {}


@st.composite
def parameter_sets(draw):
    """Up to 6 parameters with unit-suffixed names, finite or NaN standard errors, bounds, some
    held, some on a bound."""
    p = Parameters()
    for i in range(draw(st.integers(1, 6))):
        lo = draw(st.floats(-1e6, 1e6))
        hi = lo + draw(st.floats(1e-3, 1e6))
        value = draw(st.floats(lo, hi))
        err = draw(st.one_of(st.just(math.nan), st.floats(0.0, 1e3)))
        p.add(f"x{i}_{draw(st.sampled_from(['s', 'nm_per_rad', 'per_nm', 'hz']))}", value, stderr=err, min=lo, max=hi,
              vary=draw(st.booleans()))
    at = [n for n in p if draw(st.booleans())]
    return p, at


@settings(max_examples=60, derandomize=True, deadline=None)
@given(parameter_sets())
def test_every_parameter_set_serialises_and_prints_alike_for_both_kinds_of_data(drawn):
    params, at_bounds = drawn
    for make in (servo_result, drop_result):
        r = make()
        r.params, r.at_bounds = Parameters.of(list(params.values())), at_bounds
        doc = json.loads(json.dumps(r.to_dict(), allow_nan=False))
        assert list(doc) == list(RESULT_KEYS) and doc["n_parameters"] == len(params)
        for name, p in params.items():
            entry = doc["parameters"][name]
            assert entry["value"] == p.value and entry["min"] == p.min and entry["max"] == p.max
            assert entry["stderr"] == (p.stderr if math.isfinite(p.stderr) else None)
            assert entry["vary"] is p.vary and entry["at_bound"] is (name in at_bounds) and entry["unit"] == p.unit
        text = r.summary()
        assert _sections(text) == list(SUMMARY_SECTIONS)
        lines = [line for line in text.splitlines() if line.startswith("    x")]
        assert [line.split()[0] for line in lines] == list(params)
        for line, p in zip(lines, params.values()):
            assert float(line.split()[1]) == pytest.approx(p.value, rel=1e-5, abs=1e-300)
            assert line.endswith("(at bound)") is (p.name in at_bounds)
            assert line.endswith("(held)") is (p.name not in at_bounds and not p.vary)


def test_a_format_that_strays_from_the_schema_is_refused(monkeypatch):
    from droptower.identify import result

    to_dict, text = result.FORMATS[SERVO]
    monkeypatch.setitem(result.FORMATS, SERVO, (lambda ident: {**to_dict(ident), "time_s": 1.0}, text))
    with pytest.raises(RuntimeError, match="time_s"):
        servo_result().to_dict()


def test_the_servo_search_summary_is_read_under_one_name():
    r = servo_result(extra={"global_search": {"candidates": 96, "local_fits": 3}})
    assert r.search == {"candidates": 96, "local_fits": 3}
    doc = r.to_dict()
    assert doc["search"] == {"candidates": 96, "local_fits": 3} and "global_search" not in doc["details"]


# ---------------------------------------------------------------------------- one text report
def _sections(text: str) -> list[str]:
    return [line for line in text.splitlines() if re.fullmatch(r"\[\[\w+\]\]", line)]


def test_summary_is_one_text_report_with_the_same_sections():
    servo, drops = servo_result().summary(), drop_result().summary()
    assert isinstance(servo, str) and isinstance(drops, str)
    assert _sections(servo) == _sections(drops) == list(SUMMARY_SECTIONS)
    for text, wall in ((servo, "1.50"), (drops, "2.00")):
        rows = {line.split()[0]: line.split() for line in text.splitlines() if line.startswith("    k") or
                line.startswith("    tau")}
        assert rows["tau2_s"][1:5] == ["0.2", "0.01", "0.01", "0.2"] and text.count("(at bound)") == 1
        assert rows["k3_nm_per_rad"][-1] == "(held)" and "    family      = zerodim6" in text
        assert f"    wall_s      = {wall}" in text and "verdict: good fit" in text
    assert "nRMSE 1.000 %" in servo and "angle nRMSE 1.000 %" in drops
    assert "global search: 64 candidates" in drops


def _public_summaries() -> list[tuple[str, ast.FunctionDef]]:
    found = []
    for path in sorted((ROOT / "droptower").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ClassDef) and not node.name.startswith("_"):
                for item in node.body:
                    if isinstance(item, ast.FunctionDef) and item.name == "summary":
                        found.append((f"{path.relative_to(ROOT)}:{node.name}", item))
    return found


def test_every_public_summary_returns_text():
    """grep ``def summary`` over the package: each one says it returns ``str`` (a dict of
    figures is ``to_dict()``)."""
    found = _public_summaries()
    assert len(found) >= 8
    wrong = [where for where, f in found if f.returns is None or ast.unparse(f.returns) != "str"]
    assert not wrong, wrong


def test_a_summary_that_was_a_dict_is_text_and_still_answers_as_the_dict():
    from droptower.identify.fit import FitResult

    stage = FitResult("joint", ["k_nm_per_rad"], np.array([1.0]), np.ones(1, bool), np.array([0.1]), [],
                      Metrics(0.1, 0.01, 0.0, 10, 10.0), 3, 1, 4, 0, 0.5, True, "ok")
    text = stage.summary()
    assert isinstance(text, str) and text.startswith("stage joint: nRMSE 1.000 %, 3 steps, 4 evaluations")
    with pytest.warns(DeprecationWarning, match=r"FitResult.summary\(\) read as a dict .* FitResult.to_dict\(\)"):
        assert text["wall_s"] == 0.5 == stage.to_dict()["wall_s"]
    with pytest.warns(DeprecationWarning):
        assert dict(text.items()) == stage.to_dict()
    assert text[:5] == "stage"  # still a str where indexed as one


# ---------------------------------------------------------------------------- old names
OLD_ATTRIBUTES = [("fit", "fit_error"), ("holdout", "holdout_error"), ("time_s", "wall_s"), ("std_error", "stderr")]


@pytest.mark.parametrize("old, new", OLD_ATTRIBUTES)
def test_old_attribute_names_warn_and_read_the_new_ones(old, new):
    r = servo_result()
    with pytest.warns(DeprecationWarning, match=f"Identification.{old} is deprecated.*Identification.{new}"):
        value = getattr(r, old)
    assert value == getattr(r, new)


@pytest.mark.parametrize("old, new, value", [("fit", "fit_error", Metrics(1.0, 0.1, 0.0, 1, 10.0)),
                                             ("holdout", "holdout_error", None), ("time_s", "wall_s", 7.0),
                                             ("_converged", "converged", False), ("_evaluations", "evaluations", 42),
                                             ("_nfev", "nfev", 17)])
def test_old_constructor_arguments_warn_and_set_the_new_ones(old, new, value):
    p = _params()
    base = {"fit_error": Metrics(0.1, 0.01, 0.0, 10, 10.0)} if old != "fit" else {}
    with pytest.warns(DeprecationWarning, match=rf"Identification\({old}=\.\.\.\)"):
        r = Identification("zerodim6", p, [], coupling=COUPLING, **base, **{old: value})
    assert getattr(r, new) == value
    with pytest.raises(TypeError, match="unexpected keyword argument 'kind'"):
        Identification("zerodim6", p, [], kind="x")


def test_the_public_constructor_arguments_override_the_stages():
    r = servo_result()
    assert (r.converged, r.evaluations, r.nfev) == (True, 10, 3) and r.stages == []
    lazy = Identification("zerodim6", _params(), [], Metrics(0.1, 0.01, 0.0, 10, 10.0), COUPLING)
    assert (lazy.converged, lazy.evaluations, lazy.nfev) == (True, 0, 0)  # no stage: nothing ran, nothing failed


def _segment():
    from droptower.identify import make_segment

    t = np.arange(200) / 1000.0
    return make_segment(t, 0.01 * np.sin(20 * t), 100.0 * np.sin(20 * t), name="s")


@pytest.mark.parametrize("call, message", [
    (lambda: importlib.import_module("droptower.identify").identify(kind="nosuch", segments=[_segment()]),
     "nosuch"),
    (lambda: importlib.import_module("droptower.identify.dropfit").identify_drops(kind="nosuch", decays=[]),
     "family 'nosuch' cannot be identified from drop tests"),
    (lambda: importlib.import_module("droptower.identify").read_drop_tests([], model="template"),
     "`family=template` needs `template`"),
    (lambda: importlib.import_module("droptower.identify").compare_models([_segment()], kinds=[]),
     "no model family given"),
    (lambda: importlib.import_module("droptower.compare.model_map").build_model_map(
        "nowhere", None, model="zerodim6", coupling_file="c.toml"), "give `family` .* or `coupling_file`"),
])
def test_old_keyword_names_warn_and_reach_the_new_parameter(call, message):
    """Each old keyword is taken as the new one (the error is the one the new keyword's value
    gives), with a DeprecationWarning naming both."""
    with pytest.warns(DeprecationWarning, match=r"\((kind|model|kinds)=\.\.\.\) is deprecated"):
        with pytest.raises(DroptowerError, match=message):
            call()


def test_an_old_keyword_with_its_new_name_is_refused():
    from droptower.identify import identify_from_drop_tests

    with pytest.raises(TypeError, match="got 'family' and its old name 'model'"):
        identify_from_drop_tests([], "zerodim6", model="zerodim6")


def test_every_renamed_keyword_names_a_parameter_that_exists():
    """The decorated functions have the new names in their signatures, not the old."""
    import inspect

    from droptower.compare.model_map import build_model_map, read_logs_for_model
    from droptower.design.identification import design_for_identification
    from droptower.identify import compare_models, identify, identify_from_drop_tests, read_drop_tests
    from droptower.identify.dropfit import identify_drops

    for func in (identify, identify_drops, read_drop_tests, identify_from_drop_tests, compare_models, build_model_map,
                 read_logs_for_model, design_for_identification):
        names = set(inspect.signature(func).parameters)
        for old, new in func.renamed_keywords.items():
            assert new in names and old not in names, func.__name__
            assert new in {"family", "families"}


@pytest.mark.parametrize("old, new, name", [("droptower.identify.compare", "droptower.identify.ranking", "compare_models"),
                                            ("droptower.identify.drops", "droptower.identify.drop_campaign",
                                             "identify_from_drop_tests")])
def test_a_renamed_module_warns_and_is_the_new_one(old, new, name, monkeypatch):
    monkeypatch.delitem(sys.modules, old, raising=False)
    with pytest.warns(DeprecationWarning, match=f"{old} is deprecated.*import {new}"):
        module = importlib.import_module(old)
    assert module is importlib.import_module(new) and getattr(module, name).__module__ == new


@pytest.mark.parametrize("module, old, new", [
    ("droptower", "validate_map", "compare_with_servo"),
    ("droptower.compare", "validate_map", "compare_with_servo"),
    ("droptower.compare", "Validation", "ServoComparison"),
    ("droptower.compare.map_vs_servo", "Validation", "ServoComparison"),
])
def test_renamed_names_warn_and_are_the_new_objects(module, old, new):
    m = importlib.import_module(module)
    m.__dict__.pop(old, None)  # a lazy name stored on first use would skip the warning
    with pytest.warns(DeprecationWarning, match=f"{old} is deprecated"):
        got = getattr(m, old)
    assert got is getattr(importlib.import_module("droptower.compare.map_vs_servo"), new)


def test_validate_map_warns_and_compares_with_the_servo(monkeypatch):
    from droptower.compare import map_vs_servo

    monkeypatch.setattr(map_vs_servo, "compare_with_servo", lambda fit, points: ("compared", fit, points))
    with pytest.warns(DeprecationWarning, match=r"validate_map\(\) is deprecated.*compare_with_servo\(\)"):
        assert map_vs_servo.validate_map(1, 2) == ("compared", 1, 2)


def test_as_dict_is_to_dict_with_a_warning_on_the_extraction_result_too(monkeypatch):
    from droptower.extract.result import ExtractionResult

    monkeypatch.setattr(ExtractionResult, "to_dict", lambda self: {"stiffness_nm_per_deg": 1.0})
    r = object.__new__(ExtractionResult)  # what is tested is the old name's route, not an extraction
    with pytest.warns(DeprecationWarning, match=r"ExtractionResult.as_dict\(\) is deprecated.*to_dict\(\)"):
        assert r.as_dict() == {"stiffness_nm_per_deg": 1.0}


def test_the_design_names_its_family(monkeypatch):
    import pandas as pd

    from droptower.design import outputs
    from droptower.design.identification import IdentificationDesign

    monkeypatch.setattr(outputs, "condition_records", lambda conditions: [])  # not what is tested here

    d = IdentificationDesign("zerodim6", pd.DataFrame({"repeats": [2, 1]}),
                             pd.DataFrame({"parameter": ["k_nm_per_rad"], "value": [2.0], "stderr": [0.1],
                                           "relative_stderr": [0.05]}), 1.0)
    assert d.to_dict()["family"] == "zerodim6" and d.to_dict()["predicted_stderr"]["k_nm_per_rad"]["stderr"] == 0.1
    with pytest.warns(DeprecationWarning, match="IdentificationDesign.model"):
        assert d.model == "zerodim6"


# ---------------------------------------------------------------------------- the command line
@pytest.mark.parametrize("args, old, new", [
    (["identify", "no_such.csv", "--model", "pfeffer"], "--model", "--family"),
    (["compare-models", "no_such.csv", "--models", "pfeffer"], "--models", "--families"),
    (["map", "no_such_results.csv", "--model", "zerodim6"], "--model", "--family"),
])
def test_old_flags_are_hidden_and_say_they_are_deprecated(args, old, new, capsys):
    from droptower.cli.main import cli, main

    assert main(args) == 2
    err = capsys.readouterr().err
    assert f"droptower: warning: {old} is deprecated and will be removed in the next release: use {new}" in err
    assert "no_such" in err and "Traceback" not in err  # the command ran on: the old flag was taken
    helptext = CliRunner().invoke(cli, [args[0], "--help"]).output
    assert f"{new} " in helptext and not re.search(rf"{old}[ ,\n]", helptext)
    assert main([*args, new, "masing"]) == 2
    assert "given twice" in capsys.readouterr().err


# ---------------------------------------------------------------------------- the top level
def test_the_entry_points_are_at_the_top_level():
    import droptower.identify as ident
    from droptower.identify.strategies import identify

    assert droptower.read_drop_tests is ident.read_drop_tests
    assert droptower.identify_from_servo_records is identify
    assert droptower.identify_from_drop_tests is ident.identify_from_drop_tests
    assert droptower.compare_with_servo is importlib.import_module("droptower.compare").compare_with_servo
    assert {"read_drop_tests", "identify_from_servo_records", "identify_from_drop_tests"} <= set(droptower.__all__)
    assert "validate_map" not in droptower.__all__


def test_no_warning_from_the_library_itself_on_the_new_names():
    """The library uses only the new names: building, converting and printing both kinds of
    result raises no DeprecationWarning."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        for r in (servo_result(), drop_result()):
            r.to_dict(), r.summary(), r.to_frame(), repr(r)
            assert math.isfinite(r.nrmse)


def test_drop_kinds_is_drop_families_with_a_warning():
    """``dropfit.DROP_KINDS`` (release 0.1) is the tuple now named ``DROP_FAMILIES``."""
    from droptower.identify import dropfit

    with pytest.warns(DeprecationWarning, match="DROP_KINDS is deprecated.*DROP_FAMILIES"):
        assert dropfit.DROP_KINDS is dropfit.DROP_FAMILIES
