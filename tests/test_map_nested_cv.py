"""Nested cross-validation of ``map --form auto``: each outer fold chooses the terms without its
tests. With a single candidate there is nothing to choose and it is the map's own
cross-validation, to round-off; with several, every fold records its own choice."""
from __future__ import annotations

import numpy as np
import pytest

import droptower.maps.nested as nested
import droptower.maps.select as selection
from droptower.cli.main import main
from droptower.maps import read_results, select_tests
from droptower.maps.forms import Equation, MapForm
from droptower.maps.results import REQUIRED
from droptower.maps.select import cv_groups, fit_form


@pytest.fixture(scope="module")
def table4():
    tests = select_tests(read_results("rapp2022_table4"), "rapp2022_table4")[0]
    a, f, c, d = (tests[col].to_numpy(float) for col in REQUIRED)
    groups, _ = cv_groups(tests)
    return a, f, c, d, groups


def test_one_candidate_is_the_plain_cross_validation(table4, monkeypatch):
    a, f, c, d, groups = table4
    monkeypatch.setattr(nested, "AUTO_STIFFNESS_TERMS", ("exp_amplitude", "sqrt_frequency"))
    monkeypatch.setattr(nested, "AUTO_RATIO_TERMS", ("constant", "exp_amplitude"))
    # one candidate per equation: the whole (patched) library
    monkeypatch.setattr(nested, "_candidates", lambda library, need: iter([Equation(library)]))
    result = nested.nested_cv(a, f, c, d, groups)
    form = MapForm("x", Equation(("exp_amplitude", "sqrt_frequency")), Equation(("constant", "exp_amplitude")))
    plain = fit_form(form, a, f, c, d, groups, "loo")
    np.testing.assert_allclose(result.stiffness_errors, plain.stiffness_cv_errors, rtol=0, atol=1e-9)
    np.testing.assert_allclose(result.damping_errors, plain.damping_cv_errors, rtol=0, atol=1e-9)


def test_each_fold_chooses_among_the_candidates(table4, monkeypatch):
    a, f, c, d, groups = table4
    monkeypatch.setattr(nested, "AUTO_STIFFNESS_TERMS", ("exp_amplitude", "sqrt_frequency"))
    monkeypatch.setattr(nested, "AUTO_RATIO_TERMS", ("constant", "exp_amplitude"))
    result = nested.nested_cv(a, f, c, d, groups, inner_folds=3)
    assert len(result.chosen) == np.unique(groups).size
    assert {s for s, _ in result.chosen} <= {("exp_amplitude",), ("exp_amplitude", "sqrt_frequency")}
    assert np.all(np.isfinite(result.damping_errors)) and 0 < result.damping_ratio_rms_pct < 100
    assert "x)" in nested.chosen_summary(result)


def test_nested_cv_needs_auto(capsys):
    assert main(["map", "rapp2022_table4", "--nested-cv"]) == 2
    assert "--form auto" in capsys.readouterr().err


def test_map_prints_the_nested_error_next_to_the_fit(monkeypatch, capsys):
    import json

    # the outer fit chooses from the same small library as the nested folds (the full library's
    # choice on Table 4 is test_map_forms.py's): this test is about the command printing both
    for module in (nested, selection):
        monkeypatch.setattr(module, "AUTO_STIFFNESS_TERMS", ("exp_amplitude", "sqrt_frequency"))
        monkeypatch.setattr(module, "AUTO_RATIO_TERMS", ("constant", "exp_amplitude"))
    assert main(["map", "rapp2022_table4", "--form", "auto", "--nested-cv", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    got = doc["nested_cross_validation"]
    assert got["outer"] == doc["cross_validation"] == "leave-one-out (30 folds)"
    assert got["inner_folds"] == nested.INNER_FOLDS and 0 < got["damping_ratio_rms_error_pct"] < 100
