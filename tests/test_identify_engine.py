"""The drop-test identification engine's contract with its caller: the user's bounds hold in
every search of every family, the fit's options are honoured, unknown options are refused by
name. Small virtual campaigns (three decays of the family's own first-guess coupling on the
identification's lever model) and few evaluations: what is tested is where the values may go
and which settings the searches use, not the accuracy (tests/test_identify_drops.py)."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import droptower.identify.dropfit as dropfit
import droptower.identify.engine.problem as engine_problem
import droptower.identify.engine.search as engine_search
import droptower.identify.families.filled_rubber as filled_rubber_module
from droptower.errors import DroptowerError
from droptower.identify.data import DataScale
from droptower.identify.dropfit import DropFitSettings, identify_drops
from droptower.identify.droplogs import DropDecay
from droptower.identify.families import family_class
from droptower.identify.families.filled_rubber import FilledRubberFamily
from droptower.identify.families.stages import setup_family
from droptower.identify.lever import free_decay

DT = 1 / 4800
SCALE = DataScale(0.02, 0.02, 200.0, 1e4, 1.0, 30.0)
#: The families a drop campaign identifies without a template, with the options that keep them small.
FAMILIES = {"elastoslide": {}, "zerodim6": {}, "masing": {}, "pfeffer": {}, "filled_rubber": {"n": 8}}
#: Few evaluations per local fit: the searches run every stage, cheaply.
QUICK = DropFitSettings(holdout_fraction=0.0, conditioning=None, max_nfev=3)


def _decays(kind: str, seed: int = 0, n_tests: int = 3, duration_s: float = 0.04) -> list[DropDecay]:
    """Free decays of the family's first-guess coupling (0.1 % white angle noise, seeded)."""
    fam = family_class(kind)(SCALE, FAMILIES[kind] or None)
    coupling = fam.coupling(fam.initial())
    inertia, rate = np.resize([0.1557, 0.359, 0.5233], n_tests), np.resize([0.5, 2.0, 4.0], n_tests)
    n = int(duration_s / DT)
    angle, _ = free_decay(coupling, inertia, rate, n, DT)
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n_tests):
        amp = float(np.max(np.abs(angle[i])))
        out.append(DropDecay(f"test_{i}", np.arange(1, n + 1) * DT, angle[i, 1:] + 1e-3 * amp * rng.standard_normal(n),
                             None, float(inertia[i]), float(rate[i]), "impact_force", 30.0, amp, DT,
                             angle_noise_rad=1e-3 * amp))
    return out


@pytest.fixture
def local_fits(monkeypatch):
    """Every local fit of the drop engine (its bounds, evaluation limit and outcome), recorded."""
    calls = []
    original = engine_search.local_fit

    def spy(problem, x0, free=None, **kw):
        out = original(problem, x0, free, **kw)
        calls.append({"bounds": {p.name: (p.lower, p.upper) for p in problem.parameters},
                      "max_nfev": kw.get("max_nfev"), "values": np.array(out.values, float)})
        return out

    monkeypatch.setattr(engine_search, "local_fit", spy)
    return calls


def _narrow_bounds(kind: str, positions: list[tuple[float, float]]) -> dict[str, tuple[float, float]]:
    """Bounds inside the family's defaults: for parameter i (those the positions reach), the
    sub-interval between fractions positions[i] of its range (in log for logarithmic ones)."""
    fam = family_class(kind)(SCALE, FAMILIES[kind] or None)
    out = {}
    for p, (a, b) in zip(fam.parameters, positions):
        if p.name == "p" or abs(a - b) < 0.05:
            continue
        lo, hi = sorted((a, b))
        if p.log:
            ln = np.log([p.lower, p.upper])
            out[p.name] = (float(np.exp(ln[0] + lo * np.diff(ln)[0])), float(np.exp(ln[0] + hi * np.diff(ln)[0])))
        else:
            out[p.name] = (p.lower + lo * (p.upper - p.lower), p.lower + hi * (p.upper - p.lower))
    return out


def _inside(values: np.ndarray | dict, names: list[str], bounds: dict[str, tuple[float, float]]) -> list[str]:
    """The names whose value lies outside its bounds (a relative 1e-12 of rounding allowed)."""
    get = (lambda n: values[n]) if isinstance(values, dict) else (lambda n: values[names.index(n)])
    return [n for n, (lo, hi) in bounds.items()
            if not lo - 1e-12 * abs(lo) <= get(n) <= hi + 1e-12 * abs(hi)]


def test_filled_rubbers_first_search_keeps_the_users_bounds():
    """The family without its stiffening branch (the first drop-test search's) has the user's
    bounds, not the defaults it would be rebuilt with."""
    fam = FilledRubberFamily(SCALE, {"n": 8})
    bounds = {"k_nm_per_rad": (0.5 * SCALE.stiffness_nm_per_rad, 0.6 * SCALE.stiffness_nm_per_rad),
              "tau_v_s": (1e-3, 2e-3)}
    setup_family(fam, None, bounds)
    first = fam.without_branch()
    assert {p.name: (p.lower, p.upper) for p in first.parameters if p.name in bounds} == bounds
    assert not first.options["stiffening_branch"]


def test_filled_rubbers_drop_fit_keeps_the_users_bounds_in_every_search(local_fits, monkeypatch):
    """Bounds far from the first guess: every local fit (the first search's without the branch
    included) searches inside them, and the reported values lie inside the printed min/max.
    The first guess runs one start of its closed-form fit instead of 12 (where the searches
    start, not where they may go)."""
    monkeypatch.setattr(filled_rubber_module, "GUESS_STARTS", 1)
    k = SCALE.stiffness_nm_per_rad
    bounds = {"k_nm_per_rad": (2.0 * k, 3.0 * k), "kf_nm_per_rad": (0.01 * k, 0.02 * k), "tau_v_s": (1e-3, 2e-3)}
    result = identify_drops("filled_rubber", _decays("filled_rubber"), settings=QUICK, bounds=bounds,
                            options=FAMILIES["filled_rubber"])
    assert local_fits
    for call in local_fits:
        assert {n: call["bounds"][n] for n in bounds} == bounds
        assert not _inside(call["values"], list(call["bounds"]), bounds)
    for name, (lo, hi) in bounds.items():
        p = result.params[name]
        assert (p.min, p.max) == (lo, hi) and lo <= p.value <= hi


#: Random bound sets per family in :func:`test_every_reported_value_lies_in_its_printed_bounds`:
#: the cheap families (a fraction of a second per fit) get more.
BOUND_EXAMPLES = {"elastoslide": 3, "filled_rubber": 3, "masing": 3, "pfeffer": 12, "zerodim6": 6}


@pytest.mark.parametrize("kind", sorted(FAMILIES))
def test_every_reported_value_lies_in_its_printed_bounds(kind):
    """Random bounds inside the defaults, on random parameters of every family: every local fit
    of every search (first, wider, hops, loose prior) stays inside them, and so does every
    reported value inside its printed min/max.

    Each family is a case of its own with :data:`BOUND_EXAMPLES` random bound sets (a draw over
    the families, 25 examples, gave 2-3 to each slow family and the rest to pfeffer). The
    filled_rubber first guess runs one start of its closed-form fit instead of 12: the guess is
    only where the searches start, and the claim is where they may go (every search stage still
    runs: the deferred branch freed, the loose prior, measured on every example)."""

    @settings(max_examples=BOUND_EXAMPLES[kind], deadline=None, derandomize=True)
    @given(positions=st.lists(st.tuples(st.floats(0, 1), st.floats(0, 1)), min_size=20, max_size=20))
    def check(positions):
        calls = []
        original = engine_search.local_fit

        def spy(problem, x0, free=None, **kw):
            out = original(problem, x0, free, **kw)
            calls.append(({p.name: (p.lower, p.upper) for p in problem.parameters}, np.array(out.values, float)))
            return out

        bounds = _narrow_bounds(kind, positions)
        with pytest.MonkeyPatch.context() as mp:
            mp.setattr(engine_search, "local_fit", spy)
            mp.setattr(filled_rubber_module, "GUESS_STARTS", 1)
            result = identify_drops(kind, _decays(kind), settings=QUICK, bounds=bounds, options=FAMILIES[kind])
        assert calls
        for searched, values in calls:
            assert not _inside(values, list(searched), bounds)
        for p in result.params.values():
            assert p.min <= p.value <= p.max, p
        for name, (lo, hi) in bounds.items():
            assert (result.params[name].min, result.params[name].max) == (lo, hi)

    check()


def test_the_fits_options_set_the_searches_evaluation_limit_and_step(local_fits, monkeypatch):
    """``options={"max_nfev": 7, "substeps": 2}`` reach every local fit and every re-simulation
    (half the step; the bias estimate's at a quarter)."""
    steps = []
    original = engine_problem.free_decay

    def spy(coupling, inertia, rate0, n_steps, h, *args, **kw):
        steps.append(h)
        return original(coupling, inertia, rate0, n_steps, h, *args, **kw)

    monkeypatch.setattr(engine_problem, "free_decay", spy)
    identify_drops("zerodim6", _decays("zerodim6"), settings=DropFitSettings(holdout_fraction=0.0, conditioning=None),
                   options={"max_nfev": 7, "substeps": 2})
    assert local_fits and {c["max_nfev"] for c in local_fits} == {7}
    assert set(np.round(np.array(steps) / DT, 12)) == {0.5, 0.25}


@pytest.mark.parametrize("options, message", [
    ({"max_nfev": 3, "foo": 1}, "unknown option(s) foo for family zerodim6"),
    ({"cycles": 2}, "option(s) cycles apply to reading the logs"),
    ({"substeps": 0}, "option substeps must be a positive integer, got 0"),
])
def test_options_the_fit_cannot_honour_are_refused_by_name(options, message):
    with pytest.raises(DroptowerError) as err:
        identify_drops("zerodim6", _decays("zerodim6"), settings=QUICK, options=options)
    assert message in str(err.value)


def test_a_fit_option_given_twice_with_two_values_is_refused():
    from droptower.identify.dropfit import split_options

    with pytest.raises(DroptowerError, match="max_nfev = 5 contradicts the settings' max_nfev = 3"):
        split_options(QUICK, {"max_nfev": 5})
    same, rest = split_options(QUICK, {"max_nfev": 3, "seed": 4, "conditioning": False})
    assert (same.max_nfev, same.seed, same.conditioning, rest) == (3, 4, None, {})
    assert split_options(DropFitSettings(), {"conditioning": True})[0].conditioning == DropFitSettings().conditioning
    assert math.isclose(split_options(DropFitSettings(), {"torque_weight": 0})[0].torque_weight, 0.0)


def test_the_result_type_is_imported_from_where_it_is_defined():
    """``droptower.identify.fit`` no longer re-exports the result type: the old import still
    works for one release, with a DeprecationWarning; no module of the package uses it."""
    import pathlib

    import droptower.identify.fit as fit
    from droptower.identify.result import Identification

    with pytest.warns(DeprecationWarning, match="import Identification from droptower.identify"):
        assert fit.Identification is Identification
    root = pathlib.Path(fit.__file__).parents[1]
    users = [str(p.relative_to(root)) for p in root.rglob("*.py")
             if "from droptower.identify.fit import" in p.read_text() and "Identification" in
             "".join(line for line in p.read_text().splitlines() if "droptower.identify.fit import" in line)]
    assert not users


def test_rows_the_core_refuses_have_one_policy_everywhere(monkeypatch):
    """A row with any non-finite sample costs inf wherever costs are compared (the search's
    candidates, the servo candidates' batch) and is REFUSED_RESIDUAL for the optimiser; a row
    refused on a single sample is never cheaper than a finite one (a sum that skipped NaN made
    a wholly refused row cost 0)."""
    import droptower.identify.fit as fit
    from droptower.identify.data import make_segment
    from droptower.identify.engine.search import costs

    r = np.array([[1.0, 2.0], [np.nan, 0.0], [np.inf, np.nan], [0.5, 0.5]])
    assert fit.row_costs(r).tolist() == [5.0, math.inf, math.inf, 0.5]
    assert costs(lambda rows: r[rows[:, 0].astype(int)], np.arange(4.0)[:, None], batch=3).tolist() == \
        [5.0, math.inf, math.inf, 0.5]
    assert fit.finite_residuals(r)[1].tolist() == [fit.REFUSED_RESIDUAL, 0.0]

    t = np.arange(50) / 1000.0
    seg = make_segment(t, 0.01 * np.sin(40 * t), 100.0 * 0.01 * np.sin(40 * t), name="s")

    def simulate(model, values, segments, counter=None):
        """Torque k * angle; the second candidate diverges on one sample, the third on all."""
        out = []
        for k, refused in values:
            torque = k * seg.angle_rad
            if refused == 1:
                torque[3] = np.nan
            if refused == 2:
                torque[:] = np.nan
            out.append([torque])
        return out

    monkeypatch.setattr(fit, "simulate", simulate)
    best, c = fit.batch_search(None, [seg], np.array([[90.0, 0], [100.0, 1], [100.0, 2]]))
    assert best == 0 and 0 < c[0] < math.inf and c[1] == c[2] == math.inf


def test_as_dict_is_to_dict_with_a_deprecation_warning():
    """One name for a result's data (``to_dict``): the old ``as_dict`` of Metrics, Verdict and
    Comparison, and FitResult's dict-valued ``summary()``, keep working for one release with a
    DeprecationWarning and return what ``to_dict`` returns."""
    import pandas as pd

    from droptower.identify import Comparison
    from droptower.identify.fit import FitResult
    from droptower.identify.result import Metrics
    from droptower.identify.verdict import judge

    m = Metrics(2.0, 0.01, 0.1, 100, 200.0)
    v = judge(1.0, 0.5, "nm", [])
    c = Comparison(pd.DataFrame({"family": ["zerodim6"], "status": ["converged"], "bic": [1.0],
                                 "verdict": ["good fit"]}, index=[1]), None, {})
    f = FitResult("joint", ["k_nm_per_rad"], np.array([1.0]), np.array([True]), np.array([0.1]), [], m, 3, 1, 5, 2,
                  0.5, True, "ok")
    assert m.to_dict()["rmse_nm"] == 2.0 and v.to_dict()["noise_floor_nm"] == 0.5
    assert c.to_dict()["ranking"][0]["family"] == "zerodim6" and f.to_dict()["free"] == ["k_nm_per_rad"]
    for obj, old in ((m, "as_dict"), (v, "as_dict"), (c, "as_dict")):
        with pytest.warns(DeprecationWarning, match=f"{type(obj).__name__}.{old}\\(\\) is deprecated"):
            assert getattr(obj, old)() == obj.to_dict()
    # FitResult.summary() is text now (as every summary); read as the old dict it still answers, warning
    assert f.summary().startswith("stage joint: nRMSE 1.000 %")
    with pytest.warns(DeprecationWarning, match=r"FitResult.summary\(\) read as a dict is deprecated"):
        assert dict(f.summary().items()) == f.to_dict()


def test_the_evaluations_reported_are_every_parameter_set_simulated(monkeypatch):
    """One count per identification: the problems made from the fitting tests (the search's
    dozen tests of a larger campaign, the family without its deferred part) share one counter,
    so the reported evaluations are the parameter sets simulated, none added by hand."""
    calls = []
    original = dropfit.DropProblem.simulate

    def spy(self, rows, substeps=None):
        calls.append((id(self.counter), np.atleast_2d(rows).shape[0]))
        return original(self, rows, substeps)

    monkeypatch.setattr(dropfit.DropProblem, "simulate", spy)
    decays = _decays("zerodim6", n_tests=14, duration_s=0.03)  # more than the search's SEARCH_TESTS
    assert len(decays) > dropfit.SEARCH_TESTS
    result = identify_drops("zerodim6", decays, settings=QUICK)
    assert len({c for c, _ in calls}) == 1
    assert result.evaluations == sum(m for _, m in calls) > 0


def test_compare_models_refuses_options_of_a_family_it_does_not_rank():
    """Options keyed by a family outside ``kinds`` (a misspelt or forgotten one) are refused by
    name, not ignored."""
    from droptower.identify import compare_models

    with pytest.raises(DroptowerError, match="options given for zerodim7, which is not among the families ranked"):
        compare_models(_decays("zerodim6"), ["zerodim6"], options={"zerodim7": {"max_nfev": 3}})


def test_a_row_the_core_refuses_is_nan_in_every_problem_and_never_stops_a_fit():
    """The one fallback for parameter sets the core refuses: the servo records' problem and the
    drop tests' give NaN residuals for that row (the others as alone), the search's costs inf,
    and a local fit whose trial step lands there goes on (it sees REFUSED_RESIDUAL) instead of
    raising, in both problems alike."""
    from droptower.identify.data import make_segment
    from droptower.identify.engine import DropProblem, ServoProblem, local_fit
    from droptower.identify.families.zerodim6 import ZeroDim6

    class Refusing(ZeroDim6):
        """zerodim6 whose couplings the core refuses above k1 = 2 x the scale's stiffness."""

        def coupling(self, v, **kw):
            if v[0] > 2 * SCALE.stiffness_nm_per_rad:
                raise DroptowerError("refused")
            return super().coupling(v, **kw)

    fam = Refusing(SCALE)
    good = fam.initial()
    bad = good.copy()
    bad[0] = 3 * SCALE.stiffness_nm_per_rad
    t = np.arange(200) * DT
    angle = 0.01 * np.sin(2 * np.pi * 30 * t)
    seg = make_segment(t, angle, fam.coupling(good).respond(angle, DT), name="s")
    for problem in (ServoProblem(fam, [seg]), DropProblem(fam, _decays("zerodim6", n_tests=2), QUICK)):
        both = problem.residuals(np.array([good, bad]))
        assert np.isnan(both[1]).all() and np.isfinite(both[0]).all()
        np.testing.assert_array_equal(both[0], problem.residuals(good[None])[0])
        assert problem.costs(np.array([good, bad])).tolist()[1] == math.inf
        near = good.copy()
        near[0] = 1.999 * SCALE.stiffness_nm_per_rad  # the first trial steps cross into the refused region
        fit = local_fit(problem, near, max_nfev=5)
        assert np.isfinite(fit.cost) and fit.values[0] <= 2 * SCALE.stiffness_nm_per_rad


def test_the_engines_old_names_keep_working_for_one_release_with_a_warning():
    """``fit_rows``, ``RowsFit``, ``global_fit``, ``walk_p`` (now the engine's ``local_fit``,
    ``LocalFit``, ``run_search``, ``walk_choice``) give what the new names give, each with a
    DeprecationWarning; a linear least-squares problem (closed form: the normal equations) is
    solved by both."""
    import droptower.identify.engine.search as engine_search_module
    import droptower.identify.families.elastoslide as elastoslide
    import droptower.identify.fit as fit
    from droptower.identify.engine import FitVariable, FunctionProblem, LocalFit, local_fit

    t = np.linspace(0.0, 1.0, 50)
    a = np.stack([np.ones_like(t), t], axis=1)
    y = 2.0 + 3.0 * t + 0.01 * np.sin(40 * t)
    exact = np.linalg.lstsq(a, y, rcond=None)[0]
    params = [FitVariable("c0", -10.0, 10.0, log=False), FitVariable("c1", -10.0, 10.0, log=False)]

    def residuals(rows):
        return np.atleast_2d(rows) @ a.T - y

    new = local_fit(FunctionProblem(params, residuals), np.array([0.5, 0.5]), tol=1e-12)
    np.testing.assert_allclose(new.values, exact, rtol=1e-8)
    with pytest.warns(DeprecationWarning, match="fit_rows is deprecated"):
        old = fit.fit_rows(params, np.array([0.5, 0.5]), residuals, tol=1e-12)
    np.testing.assert_array_equal(old.values, new.values)
    with pytest.warns(DeprecationWarning, match="RowsFit is deprecated"):
        assert fit.RowsFit is LocalFit
    with pytest.warns(DeprecationWarning, match="global_fit is deprecated"):
        best, summary = engine_search_module.global_fit(params, np.array([0.5, 0.5]), residuals,
                                                        free=np.ones(2, bool), n_candidates=8, tol=1e-12)
    np.testing.assert_allclose(best.values, exact, rtol=1e-8)
    assert summary["candidates"] == 8 and summary["local_fits"] == 3
    with pytest.warns(DeprecationWarning, match="walk_p is deprecated"):
        assert elastoslide.walk_p is engine_search_module.walk_choice


def test_a_diverging_simulation_is_refused_not_a_crash_of_the_solver():
    """A parameter set whose simulation diverges without overflowing (residuals of 1e298, as a
    pfeffer coupling with a stiff beta gave on narrowed bounds) counts as refused: its squares
    would overflow inside the trust-region solver, whose SVD then raised ValueError ("array
    must not contain infs or NaNs") out of identify_drops."""
    from droptower.identify.engine import local_fit
    from droptower.identify.engine.problem import REFUSED_RESIDUAL, FitVariable, FunctionProblem, finite_residuals

    r = np.array([1.0, -2.0, 1e298, -1e298, np.nan, np.inf])
    np.testing.assert_array_equal(finite_residuals(r), [1.0, -2.0] + [REFUSED_RESIDUAL] * 4)
    target = np.linspace(0.0, 1.0, 50)

    def residuals(rows):  # a least-squares slope, diverging beyond 2
        out = rows[:, :1] * target[None, :] - target[None, :]
        return np.where(rows[:, :1] > 2.0, 1e298, out)

    fit = local_fit(FunctionProblem([FitVariable("a", 0.1, 10.0, log=False)], residuals), np.array([1.99]))
    assert np.isfinite(fit.cost) and abs(fit.values[0] - 1.0) < 1e-6
