"""The identification engine gives the numbers it gave before its layers were rebuilt: for a
small fixed set of fits (servo records of three cheap families, each with and without the
global search; drop campaigns of six virtual tests, with and without the rig's conditioning,
which sends a fit through escalation, basin moves, a deferred branch and the loose prior), the
fitted values, the cost, the verdict's error over the allowance and the evaluation count are
stored (tests/data/regression/test_engine_regression.json) and compared: values and costs to
1e-9 relative (the same floating-point operations in the same order give the same digits; the
tolerance leaves room for a BLAS that sums in another order), counts exactly."""
from __future__ import annotations

import numpy as np
import pytest

from droptower import load_coupling
from droptower.identify.dropfit import DropFitSettings, identify_drops
from droptower.identify.strategies import identify
from droptower.servo import histories as H

from test_identify_engine import _decays
from test_identify_helpers import D, coupling, records

#: Relative agreement of values and costs with the stored figures.
REL = 1e-9
FS = 256.0  # Hz: short records, cheap fits


def _servo_records(kind: str) -> list:
    truths = {"elastoslide": coupling({"kind": "elastoslide", "phi0": 0.01, "k": 20000.0, "k0": 3000.0,
                                       "v_r": 0.05, "p": 7}),
              "zerodim6": load_coupling("seed000_six_parameter"),
              "masing": coupling({"kind": "spring", "stiffness": 3000.0},
                                 {"kind": "maxwell", "stiffness": 1500.0, "damping": 15.0})}
    hist = {"amplitude_sweep": H.amplitude_sweep(D(np.array([0.3, 1.0, 2.5])), 8.0, FS, run_in_cycles=2, cycles=3),
            "frequency_sweep": H.frequency_sweep([2.0, 8.0], D(1.0), FS, run_in_cycles=2, cycles=3)}
    return records(truths[kind], hist)[0]


def _check(regression, result, cost: float) -> None:
    for name, value in result.parameters.items():
        regression.check(f"value {name}", value, REL, atol=1e-300)
    regression.check("cost", cost, REL)
    regression.check("error_over_noise", result.verdict.error_over_noise, REL)
    regression.check("poor", float(result.verdict.poor), 0.0)
    regression.check("evaluations", result.evaluations, 0.0)


@pytest.mark.parametrize("kind,search", [("elastoslide", "never"), ("zerodim6", "never"), ("zerodim6", "always"),
                                         ("masing", "never"), ("masing", "always")])
def test_servo_fit_is_unchanged(regression, kind, search):
    result = identify(kind, _servo_records(kind), search=search)
    _check(regression, result, result.fit_error.rmse_nm)


def test_servo_global_search_with_the_exponent_drawn_is_unchanged(regression):
    result = identify("elastoslide", _servo_records("elastoslide"), search="always")
    _check(regression, result, result.fit_error.rmse_nm)
    regression.check("global search candidates", result.extra["global_search"]["candidates"], 0.0)


CONDITIONED = (0.05, 0.05)  # the virtual tests were made without: a fit poor enough to escalate


@pytest.mark.parametrize("kind,conditioning", [("elastoslide", None), ("zerodim6", None), ("zerodim6", CONDITIONED),
                                               pytest.param("elastoslide", CONDITIONED, marks=pytest.mark.slow)])
def test_drop_fit_is_unchanged(regression, kind, conditioning):
    decays = _decays(kind, seed=1, n_tests=6, duration_s=0.04)
    result = identify_drops(kind, decays, settings=DropFitSettings(conditioning=conditioning))
    _check(regression, result, result.angle_rss_rad2)
    regression.check("nfev", result.nfev, 0.0)


@pytest.mark.slow
@pytest.mark.parametrize("kind,conditioning,options", [("masing", CONDITIONED, None),
                                                       ("filled_rubber", None, {"n": 8})])
def test_drop_fit_through_hops_and_a_deferred_branch_is_unchanged(regression, kind, conditioning, options):
    decays = _decays(kind, seed=1, n_tests=6, duration_s=0.04)
    result = identify_drops(kind, decays, settings=DropFitSettings(conditioning=conditioning), options=options)
    _check(regression, result, result.angle_rss_rad2)
    regression.check("nfev", result.nfev, 0.0)
    regression.check("hops", len(result.search.get("hops", [])), 0.0)


def test_drop_fit_screening_on_a_subset_of_tests_is_unchanged(regression):
    decays = _decays("elastoslide", seed=2, n_tests=16, duration_s=0.03)
    result = identify_drops("elastoslide", decays, settings=DropFitSettings(conditioning=None))
    _check(regression, result, result.angle_rss_rad2)
    regression.check("search tests", result.search["search_tests"], 0.0)
