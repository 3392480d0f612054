"""The Python API's results: one identification type with lmfit-like parameters (value,
standard error, bounds, vary, unit), accepted as input too; results that print and convert to
a table and a dict."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from droptower import load_coupling
from droptower.errors import DroptowerError
from droptower.identify import Identification, Parameter, Parameters, identify
from droptower.identify.result import place_guesses, split_given, unit_of

from test_identify_helpers import fitting_histories, records


@pytest.mark.parametrize("name, unit", [
    ("tau1_s", "s"), ("k1_nm_per_rad", "N*m/rad"), ("c_nms_per_rad", "N*m*s/rad"),
    ("k3_gain_nm_per_rad2", "N*m/rad^2"), ("a_nm_per_rad3", "N*m/rad^3"), ("phi0_per_nm", "1/(N*m)"),
    ("p_c_per_rad", "1/rad"), ("v_r_rad_per_s", "rad/s"), ("k1_n_per_m", "N/m"), ("r_nm", "N*m"),
    ("min_frequency_hz", "Hz"), ("alpha", ""), ("k_c", ""), ("matrix_loss_factor", ""), ("p", ""),
    ("c3_excess_to_v1", ""),
])
def test_the_unit_is_read_off_the_name(name, unit):
    assert unit_of(name) == unit
    assert Parameter(name, 1.0).unit == unit


finite = st.floats(-1e6, 1e6, allow_nan=False)


@st.composite
def parameter_sets(draw):
    n = draw(st.integers(1, 8))
    out = []
    for i in range(n):
        lo = draw(finite)
        hi = lo + draw(st.floats(1e-3, 1e6))
        bounded = draw(st.booleans())
        value = draw(st.one_of(st.just(math.nan), st.floats(lo, hi)))
        vary = draw(st.booleans())
        if not vary and not math.isfinite(value):
            value = lo
        out.append(Parameter(f"x{i}_s", value, min=lo if bounded else -math.inf, max=hi if bounded else math.inf,
                             vary=vary))
    return out


@settings(max_examples=200, derandomize=True, deadline=None)
@given(parameter_sets())
def test_given_parameters_split_into_held_values_bounds_and_first_guesses(params):
    held, bounds, guesses = split_given(Parameters.of(params), None)
    assert (held or {}) == {p.name: p.value for p in params if not p.vary}
    assert (bounds or {}) == {p.name: (p.min, p.max) for p in params if p.vary and math.isfinite(p.min)}
    assert guesses == {p.name: p.value for p in params if p.vary and math.isfinite(p.value)}
    # the same from a plain list, and nothing changes a dict of held values
    assert split_given(params, None) == (held, bounds, guesses)
    plain = {p.name: p.value for p in params if not p.vary}
    assert split_given(plain, {"a": (0.0, 1.0)}) == (plain, {"a": (0.0, 1.0)}, {})
    x0 = np.zeros(len(params))
    place_guesses("test", [p.name for p in params], x0, guesses)
    for i, p in enumerate(params):
        assert x0[i] == (guesses.get(p.name, 0.0))
    table = Parameters.of(params).to_frame()
    assert list(table["name"]) == [p.name for p in params] and list(table["vary"]) == [p.vary for p in params]
    json.dumps(Parameters.of(params).to_dict(), allow_nan=False)  # JSON-ready: non-finite as null


def test_bad_parameters_are_one_line_errors():
    with pytest.raises(DroptowerError, match="min 2 is above max 1"):
        Parameter("k_nm_per_rad", 1.0, min=2.0, max=1.0)
    with pytest.raises(DroptowerError, match="held .* no finite value"):
        split_given([Parameter("k_nm_per_rad", vary=False)], None)
    with pytest.raises(DroptowerError, match="give both min and max"):
        split_given([Parameter("k_nm_per_rad", 1.0, min=0.0)], None)
    with pytest.raises(DroptowerError, match="family zerodim6 has no parameter k9"):
        place_guesses("zerodim6", ["k1_nm_per_rad"], np.zeros(1), {"k9": 1.0})
    assert dict(Parameters.of({"a_s": 1.0})) == {"a_s": Parameter("a_s", 1.0, vary=False)}


@pytest.mark.slow
def test_a_servo_identification_takes_and_reports_parameters():
    """zerodim6 on the seed000 preset's records with K1's initial value and tau2's bounds given
    as parameters: the bounds come back as given, the values within the tolerances of the fit
    without them (tests/test_identify_families.py); a parameter held fixed is refused (the
    servo strategies fit every parameter)."""
    truth = load_coupling("seed000_six_parameter")
    data, _ = records(truth, fitting_histories())
    given_params = Parameters()
    given_params.add("k1_nm_per_rad", 2500.0)
    given_params.add("tau2_s", 0.3, min=0.05, max=2.0)
    r = identify("zerodim6", data, init=given_params)
    assert isinstance(r, Identification) and r.data == "servo records" and r.converged
    k1, tau2 = r.params["k1_nm_per_rad"], r.params["tau2_s"]
    assert k1.value == pytest.approx(3000.0, rel=0.01) and k1.vary and k1.unit == "N*m/rad"
    assert abs(k1.value - 3000.0) < 4 * k1.stderr
    assert (tau2.min, tau2.max) == (0.05, 2.0) and tau2.unit == "s"
    assert tau2.value == pytest.approx(0.2, rel=0.01) and abs(tau2.value - 0.2) < 4 * tau2.stderr
    # the views agree with the fitted vector (the family's order; the derived damping is the
    # family's k2 * tau2 of that vector, computed apart from the parameter views)
    assert list(r.parameters) == ["k1_nm_per_rad", "k2_nm_per_rad", "tau2_s", "k3_nm_per_rad", "k3_gain_nm_per_rad2",
                                  "tau3_s"]
    assert r.derived["c2_nms_per_rad"] == pytest.approx(r.parameters["k2_nm_per_rad"] * r.parameters["tau2_s"],
                                                        rel=1e-12)
    # the dict, the table and the text carry the preset's values (not the result's own views
    # compared with each other): tau2 = 0.2 s, K1 = 3000 N*m/rad within the fit's tolerances
    # and within 4 standard errors as each of them reports it
    doc = json.loads(json.dumps(r.to_dict(), allow_nan=False))
    entry = doc["parameters"]["tau2_s"]
    assert doc["family"] == "zerodim6" and doc["data"] == "servo records" and doc["n_parameters"] == 6
    assert entry["value"] == pytest.approx(0.2, rel=0.01) and abs(entry["value"] - 0.2) < 4 * entry["stderr"]
    assert (entry["min"], entry["max"], entry["unit"], entry["vary"]) == (0.05, 2.0, "s", True)
    table = r.to_frame().set_index("name")
    assert len(table) == 6 and table.loc["k1_nm_per_rad", "value"] == pytest.approx(3000.0, rel=0.01)
    assert abs(table.loc["k1_nm_per_rad", "value"] - 3000.0) < 4 * table.loc["k1_nm_per_rad", "stderr"]
    assert repr(r).startswith("<Identification zerodim6 from servo records: 6 parameters, converged")
    text = r.summary()
    assert "tau2_s" in r._repr_html_() and "    family      = zerodim6" in text
    row = next(line for line in text.splitlines() if line.strip().startswith("tau2_s"))
    assert float(row.split()[1]) == pytest.approx(0.2, rel=0.01) and row.split()[-1] == "s"
    held = Parameters()
    held.add("k1_nm_per_rad", 3000.0, vary=False)
    with pytest.raises(DroptowerError, match="parameter k1_nm_per_rad: an identification from servo records fits"):
        identify("zerodim6", data, init=held)


@pytest.mark.slow
def test_a_design_prints_and_converts(tmp_path):
    from droptower.design import design

    plan = design((0.5, 2.0), (25.0, 45.0), preloads_nm=(0.0,), repeats=2)
    table = plan.to_frame()
    assert len(table) == plan.n_conditions and int(table["repeats"].sum()) == plan.n_tests == 2 * plan.n_conditions
    doc = plan.to_dict()
    assert doc["tests"] == plan.n_tests and len(doc["conditions"]) == plan.n_conditions and doc["plan_file"] is None
    json.dumps(doc, allow_nan=False)
    assert repr(plan).startswith(f"<Design: {plan.n_conditions} conditions x 2 repeats")
    assert plan.summary().splitlines()[0].endswith("reachable with this rig)")
    path = plan.write(tmp_path / "plan.toml", sheet=tmp_path / "order.csv", seed=3)
    assert path.is_file() and plan.to_dict()["plan_file"] == str(path)
    with pytest.raises(DroptowerError, match="give `repeats` or `uncertainty_pct`, not both"):
        design((0.5, 2.0), (25.0, 45.0), repeats=2, uncertainty_pct=1.0)


@pytest.mark.slow
def test_a_map_and_its_validation_print_and_convert():
    """The paper's Table 4 map (Rapp et al. 2022) validated against the quick servo sweeps of the
    coupling calibrated to it: the result's table is the validation's points, its dict is JSON,
    its summary the command's text."""
    import droptower as dt
    from droptower.compare.map_vs_servo import format_summary

    fit = dt.fit_map(dt.read_results("rapp2022_table4"))
    assert repr(fit).startswith("<MapFit paper: ")
    # the table's 13 values, put into eq. 19 and eq. 20 as the paper writes them (docs/theory.md#map;
    # closed forms here, not the map's own evaluation), reproduce the map at the table's points
    k = fit.to_frame().set_index("coefficient")["value"].to_dict()
    assert sorted(k) == sorted(f"k{i}" for i in range(1, 14))
    rows = dt.read_results("rapp2022_table4")
    a_deg, f_hz = rows["amplitude_deg"].to_numpy(float), rows["frequency_hz"].to_numpy(float)
    c = (k["k1"] * 10 ** (-k["k2"] * a_deg) + k["k3"] * 10 ** (-k["k4"] * a_deg) + k["k5"] * np.sqrt(f_hz)
         + k["k6"] * 10 ** (-k["k7"] * f_hz))
    c_over_d = k["k8"] * 10 ** (-k["k9"] * a_deg) + k["k10"] * 10 ** (-k["k11"] * a_deg) + k["k12"] * 10 ** (-k["k13"] * a_deg)
    np.testing.assert_allclose(fit.stiffness_nm_per_deg(a_deg, f_hz), c, rtol=1e-12)
    np.testing.assert_allclose(fit.damping_ratio(a_deg, f_hz), c / c_over_d, rtol=1e-12)
    v = dt.validate(fit, "rapp2022_nr60", quick=True)
    table = v.to_frame()
    assert len(table) == len(v.validation.table) > 0
    doc = v.to_dict()
    json.dumps(doc, allow_nan=False)
    assert doc["summary"] == json.loads(json.dumps(doc["summary"])) and len(doc["points"]) == len(table)
    assert v.summary().startswith(format_summary(v.validation)) and "reference" not in doc
    assert repr(v).startswith(f"<MapValidation: {len(table)} servo points")
    with pytest.raises(DroptowerError, match="`results` needs `reference`"):
        dt.validate(fit, results="campaign")


def test_a_comparison_prints_and_converts():
    """A ranking as compare_models builds it: the best converged family, the table, JSON."""
    import pandas as pd

    from droptower.identify import Comparison

    ranking = pd.DataFrame({"family": ["zerodim6", "pfeffer"], "status": ["converged", "not converged"],
                            "bic": [10.0, math.nan], "verdict": ["good fit", "not converged"]}, index=[1, 2])
    c = Comparison(ranking, None, {}, skipped={"overlay": "no sine blocks"}, not_converged={"pfeffer": "budget"})
    assert c.best == "zerodim6" and c.exit_code() == 0
    assert c.to_frame()["family"].tolist() == ["zerodim6", "pfeffer"]
    doc = json.loads(json.dumps(c.to_dict(), allow_nan=False))
    assert [row["family"] for row in doc["ranking"]] == ["zerodim6", "pfeffer"] and doc["ranking"][1]["bic"] is None
    assert doc["skipped"] == {"overlay": "no sine blocks"} and doc["not_converged"] == {"pfeffer": "budget"}
    assert repr(c) == ("<Comparison of 2 families on servo records: best zerodim6; skipped overlay; "
                       "not converged pfeffer>")
    assert "zerodim6" in c._repr_html_()
