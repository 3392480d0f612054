"""Map forms beyond eq. 19/20: cross-validation, the automatic choice of terms with
identifiability pruning, and the targets on the paper's Table 4 (shipped copy)."""
from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, seed, settings
from hypothesis import strategies as st

from droptower.cli.main import main
from droptower.data import read_table4
from droptower.errors import DroptowerError
from droptower.maps import MapFit, fit_map, model
from droptower.maps.forms import AUTO_RATIO_TERMS, AUTO_STIFFNESS_TERMS, KINDS, PAPER, VELOCITY, Equation, MapForm
from droptower.maps.results import REQUIRED
from droptower.maps import select
from droptower.maps.select import cv_groups, fit_form


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(x))))


def _errors(m: MapFit, table: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
    a, f = table["amplitude_deg"].to_numpy(float), table["frequency_hz"].to_numpy(float)
    return (m.stiffness_nm_per_deg(a, f) / table["stiffness_nm_per_deg"].to_numpy() - 1,
            m.damping_ratio(a, f) / table["damping_ratio"].to_numpy() - 1)


@pytest.fixture(scope="session")  # kept when worksteal splits this file: a second block reuses it
def table4() -> pd.DataFrame:
    return read_table4()


@pytest.fixture(scope="session")  # kept when worksteal splits this file: a second block reuses it
def auto_map(table4: pd.DataFrame) -> MapFit:
    return fit_map(table4, form="auto")


@pytest.mark.slow
def test_auto_meets_the_targets_on_table4(table4: pd.DataFrame, auto_map: MapFit) -> None:
    """The map-form targets on Table 4: damping ratio cross-validated RMS <= 8 % (the paper's
    eq. 20 fits 12.3 %), stiffness <= 1.5 % fitted and cross-validated, and every coefficient
    identifiable: off its bound, unique, uncertainty below half its value. The fit errors are
    recomputed here from the coefficients."""
    m = auto_map
    err_c, err_d = _errors(m, table4)
    print(f"\nauto on Table 4: {m.form.stiffness.terms} / {m.form.ratio.terms}: stiffness rms {_rms(err_c):.2%} "
          f"(cv {m.stats.stiffness_cv_rms_error_pct:.2f} %), damping ratio rms {_rms(err_d):.2%} "
          f"(cv {m.stats.damping_ratio_cv_rms_error_pct:.2f} %)")
    assert _rms(err_c) * 100 == pytest.approx(m.stats.stiffness_rms_error_pct, rel=1e-9)
    assert _rms(err_d) * 100 == pytest.approx(m.stats.damping_ratio_rms_error_pct, rel=1e-9)
    assert m.stats.stiffness_rms_error_pct <= 1.5 and m.stats.stiffness_cv_rms_error_pct <= 1.5
    assert m.stats.damping_ratio_cv_rms_error_pct <= 8.0
    assert m.stats.damping_ratio_rms_error_pct <= m.stats.damping_ratio_cv_rms_error_pct
    assert m.at_bounds == () and m.not_unique == ()
    for k, value in m.coefficients.items():
        assert value > 0 and np.isfinite(m.uncertainties[k]) and m.uncertainties[k] <= 0.5 * value, k
    assert m.cross_validation == "leave-one-out (30 folds)"
    # the damping depends on frequency as well as amplitude (the inertia cases' split)
    assert "exp_velocity" in m.form.ratio.terms


def test_cross_validated_error_is_what_refitting_without_each_test_gives(table4: pd.DataFrame,
                                                                         auto_map: MapFit) -> None:
    """The reported cross-validated errors are the RMS of one error per left-out test, and each
    is what the slow way gives: the chosen form fitted from scratch (full multi-start search) to
    the table without that row, predicting it. The slow way is taken for the first, the last and
    8 more rows drawn (seeded) of the 30, each within the 0.05 % the RMS was once compared to
    (measured: 7e-6 at most over all 30)."""
    form = auto_map.form
    a, f, c, d = (table4[col].to_numpy(float) for col in REQUIRED)
    groups, method = cv_groups(table4)
    folds = fit_form(form, a, f, c, d, groups, method)
    assert _rms(folds.stiffness_cv_errors) * 100 == pytest.approx(auto_map.stats.stiffness_cv_rms_error_pct, rel=1e-12)
    assert _rms(folds.damping_cv_errors) * 100 == pytest.approx(auto_map.stats.damping_ratio_cv_rms_error_pct, rel=1e-12)
    rows = [0, len(table4) - 1, *np.random.default_rng(29).choice(np.arange(1, len(table4) - 1), 8, replace=False)]
    for i in rows:
        m = fit_map(table4.drop(index=i), form=form)
        err_c, err_d = _errors(m, table4.iloc[[i]])
        assert err_c[0] == pytest.approx(folds.stiffness_cv_errors[i], abs=5e-4), i
        assert err_d[0] == pytest.approx(folds.damping_cv_errors[i], abs=5e-4), i


def test_paper_form_stays_the_default_reference(table4: pd.DataFrame) -> None:
    """The paper's form is unchanged (1.36 % / 12.33 %, test_maps) and now reports its
    cross-validated errors too: eq. 20's terms the data do not pin down cost it out of sample."""
    m = fit_map(table4)
    assert m.form == PAPER and list(m.coefficients) == [f"k{i}" for i in range(1, 14)]
    assert m.stats.damping_ratio_rms_error_pct == pytest.approx(12.33, abs=0.01)
    assert m.stats.damping_ratio_cv_rms_error_pct > 15.0  # 22.1 %: k9 at its bound, k12, k13 unidentified
    assert m.stats.stiffness_cv_rms_error_pct > m.stats.stiffness_rms_error_pct
    a, f = np.geomspace(0.1, 4, 7), np.linspace(20, 60, 7)
    np.testing.assert_allclose(m.stiffness_nm_per_deg(a, f), model.stiffness(m.stiffness_params, a, f), rtol=1e-14)
    np.testing.assert_allclose(m.damping_ratio(a, f), model.damping_ratio(m.stiffness_params, m.ratio_params, a, f),
                               rtol=1e-14)


def _velocity_table(noise: float, seed: int = 0) -> tuple[pd.DataFrame, np.ndarray, np.ndarray]:
    """Tests of a Table-2-like design from the velocity form (coefficients near Table 4's)."""
    rng = np.random.default_rng(seed)
    a = np.tile(np.geomspace(0.15, 3.2, 10), 3)
    f = np.repeat([45.0, 28.0, 23.0], 10) * a**-0.12
    ps = np.array([180.0, 1.2, 23.0, 110.0, 0.0075])
    pr = np.array([106.0, 990.0, 2.9, 350.0, 0.04])
    c = VELOCITY.stiffness.value(ps, a, f)
    d = c / VELOCITY.ratio.value(pr, a, f)
    table = pd.DataFrame({"amplitude_deg": a, "frequency_hz": f,
                          "stiffness_nm_per_deg": c * (1 + noise * rng.standard_normal(a.size)),
                          "damping_ratio": d * (1 + noise * rng.standard_normal(a.size)),
                          "drop_height_m": np.tile(np.geomspace(0.05, 6.0, 10), 3)})
    return table, ps, pr


def test_noise_free_velocity_form_gives_back_its_coefficients() -> None:
    table, ps, pr = _velocity_table(0.0)
    m = fit_map(table, form="velocity")
    np.testing.assert_allclose(m.stiffness_params, ps, rtol=1e-6)
    np.testing.assert_allclose(m.ratio_params, pr, rtol=1e-6)
    assert m.stats.damping_ratio_cv_rms_error_pct < 1e-4
    assert m.cross_validation == "leave-one-drop-height-out (10 folds)"


@pytest.mark.slow
def test_auto_prunes_terms_the_data_do_not_need() -> None:
    """Data from the velocity form with 1 % noise: auto may not report more terms than the
    truth has (every extra term's coefficient would be unidentifiable or on its bound)."""
    table, _, _ = _velocity_table(0.01, seed=3)
    m = fit_map(table, form="auto")
    assert m.at_bounds == () and m.not_unique == ()
    assert len(m.form.stiffness.terms) <= 3 and len(m.form.ratio.terms) <= 3
    assert m.stats.damping_ratio_cv_rms_error_pct < 2.0 and m.stats.stiffness_cv_rms_error_pct < 2.0


def test_cv_groups() -> None:
    table = pd.DataFrame({"drop_height_m": [0.1, 0.1, 0.5, 0.5, 1.0, 1.0]})
    groups, method = cv_groups(table)
    assert method == "leave-one-drop-height-out (3 folds)" and len(set(groups)) == 3
    groups, method = cv_groups(table.iloc[:4])  # two heights cannot be cross-validated by height
    assert method == "leave-one-out (4 folds)" and len(set(groups)) == 4


def test_form_map_json_round_trip_and_bad_form(tmp_path, auto_map: MapFit, table4: pd.DataFrame) -> None:
    path = tmp_path / "map.json"
    auto_map.to_json(path)
    back = MapFit.from_json(path)
    assert back.form == MapForm("auto", auto_map.form.stiffness, auto_map.form.ratio)
    a, f = table4["amplitude_deg"].to_numpy(), table4["frequency_hz"].to_numpy()
    np.testing.assert_array_equal(back.damping_ratio(a, f), auto_map.damping_ratio(a, f))
    assert back.stats == auto_map.stats and back.cross_validation == auto_map.cross_validation
    data = json.loads(path.read_text())
    data["form"]["ratio_terms"] = ["constant", "cubic"]
    with pytest.raises(DroptowerError, match="unknown or no term kinds"):
        MapFit.from_dict(data, "map.json")
    data = json.loads(path.read_text())
    data["form"]["ratio_terms"] = ["constant"]
    with pytest.raises(DroptowerError, match="field coefficients: field k7_nm_per_deg: not a coefficient of the form .auto."):
        MapFit.from_dict(data, "map.json")
    # a map.json of the paper form written before forms existed still reads
    old = json.loads(fit_map(table4).to_json())
    for key in ("form", "cross_validation"):
        old.pop(key)
    for key in ("stiffness_cv_rms_error_pct", "damping_ratio_cv_rms_error_pct"):
        old["fit"].pop(key)
    assert MapFit.from_dict(old).form == PAPER
    with pytest.raises(DroptowerError, match="unknown map form 'cubic'"):
        fit_map(table4, form="cubic")


def test_equation_jacobian_matches_finite_differences() -> None:
    eq = Equation(("constant", "amplitude", "exp_amplitude", "sqrt_frequency", "exp_frequency", "exp_velocity"))
    p = np.array([100.0, 5.0, 900.0, 2.0, 20.0, 50.0, 0.03, 300.0, 0.04])
    a, f = np.array([0.2, 1.0, 3.0]), np.array([50.0, 30.0, 22.0])
    num = np.stack([(eq.value(p + h, a, f) - eq.value(p - h, a, f)) / (2 * h[i])
                    for i, h in enumerate(np.diag(1e-6 * np.maximum(np.abs(p), 1)))], axis=-1)
    np.testing.assert_allclose(eq.jacobian(p, a, f), num, rtol=1e-6, atol=1e-9)


def test_map_cli_form_auto(capsys) -> None:
    assert main(["map", "rapp2022_table4", "--form", "velocity"]) == 0
    out = capsys.readouterr().out
    assert "form velocity" in out and "cross-validated" in out and "k1*10^(-k2*a) + k3*sqrt(f) + k4*10^(-k5*a*f)" in out


# ---- the search's shortcuts give what the plain evaluation gives, bit for bit -----------------
_ANY_TERMS = st.lists(st.sampled_from(sorted(KINDS)), min_size=1, max_size=5).map(tuple)


@seed(2030)
@settings(max_examples=40, deadline=None)
@given(terms=_ANY_TERMS, n=st.integers(1, 40), data=st.data())
def test_basis_on_grid_and_value_and_jacobian_are_the_plain_evaluations(terms, n, data) -> None:
    """basis_on_grid(ix) is basis(the grid's exponents at ix), and value_and_jacobian is value and
    jacobian, bit for bit, on random equations, points, grids and parameters."""
    eq = Equation(terms)
    rng = np.random.default_rng(data.draw(st.integers(0, 2**32 - 1)))
    a, f = rng.uniform(0.05, 20.0, n), rng.uniform(1.0, 120.0, n)
    grids = [np.geomspace(rng.uniform(1e-4, 1e-2), rng.uniform(1.0, 50.0), 16) for _ in eq.exponents]
    at = eq.basis_on_grid(grids, a, f)
    for _ in range(5):
        ix = tuple(int(i) for i in rng.integers(0, 16, len(grids)))
        np.testing.assert_array_equal(at(ix), eq.basis([g[i] for g, i in zip(grids, ix)], a, f), strict=True)
    p = rng.uniform(0.0, 3.0, eq.size) * np.where(np.isin(np.arange(eq.size), eq.linear), 300.0, 0.2)
    value, jac = eq.value_and_jacobian(p, a, f)
    np.testing.assert_array_equal(value, eq.value(p, a, f), strict=True)
    np.testing.assert_array_equal(jac, eq.jacobian(p, a, f), strict=True)


@seed(2031)
@settings(max_examples=3, deadline=None)
@given(stiffness=st.booleans(), data=st.data())
def test_the_search_on_the_grid_table_is_the_plain_search(table4: pd.DataFrame, stiffness: bool, data) -> None:
    """One equation fitted to noisy Table 4 as fit_equation does it (grid columns computed once,
    value and Jacobian from one basis) and with the plain evaluations: the same solutions, bit for bit."""
    from droptower.maps import solve

    library = AUTO_STIFFNESS_TERMS if stiffness else AUTO_RATIO_TERMS
    eq = Equation(tuple(data.draw(st.lists(st.sampled_from(library), min_size=1, max_size=3))))
    rng = np.random.default_rng(data.draw(st.integers(0, 2**32 - 1)))
    a, f = table4["amplitude_deg"].to_numpy(float), table4["frequency_hz"].to_numpy(float)
    target = table4["stiffness_nm_per_deg" if stiffness else "damping_ratio"].to_numpy(float)
    target = target * (1 + 0.03 * rng.standard_normal(target.size)) * (1.0 if stiffness else 1000.0)
    points, grids = select._exponent_grids(eq, a, f)
    exponents_at = lambda ix: tuple(g[i] for g, i in zip(grids, ix))  # noqa: E731
    residuals, jacobian = solve.relative_residuals(eq, stiffness, a, f, target)
    if stiffness:
        plain_jacobian = lambda p: eq.jacobian(p, a, f) / target[:, None]  # noqa: E731
    else:
        plain_jacobian = lambda p: -(target / eq.value(p, a, f) ** 2)[:, None] * eq.jacobian(p, a, f)  # noqa: E731
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        fast = solve.variable_projection(points, exponents_at, eq.basis_on_grid(grids, a, f), target, eq.linear,
                                         eq.exponents, residuals, jacobian)
        plain = solve.variable_projection(points, exponents_at, lambda ix: eq.basis(exponents_at(ix), a, f), target,
                                          eq.linear, eq.exponents, residuals, plain_jacobian)
    assert len(fast) == len(plain) >= 1
    for got, want in zip(fast, plain):
        np.testing.assert_array_equal(got.params, want.params, strict=True)
        np.testing.assert_array_equal(got.at_bound, want.at_bound, strict=True)
        assert got.ssr == want.ssr
