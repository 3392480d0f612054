"""The model ranking (one criterion on common samples), the noise floor from the data, the
global search and the verdict: against closed forms and seeded random cases."""
from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from droptower.identify.criterion import TIE, bic, order
from droptower.identify.data import make_segment
from droptower.identify.engine import FunctionProblem, SearchPolicy, local_fit, run_search
from droptower.identify.fit import FitVariable, Metrics
from droptower.identify.noise import servo_noise
from droptower.identify.report import ranking_table
from droptower.identify.engine.search import candidates, exchangeable_branches, order_branches
from droptower.identify.verdict import GOOD, NOISE_RATIO, POOR, bound_hits, judge
from shared_fits import share_fits


@pytest.fixture(scope="module", autouse=True)
def fits(request):
    """One fit per distinct call in this module (tests/shared_fits.py): the first zerodim6 draw's fit is
    ranked in one test and followed by zerodim20 in another."""
    with share_fits(request.module, keep=__name__) as cache:
        yield cache


def test_criterion_is_unit_free_and_penalises_parameters():
    base = bic(rss=2.0e4, n_samples=10_000, n_eff=10_000.0, sigma=1.5, n_parameters=6)
    # the torque in another unit (x 1000): the same score
    assert bic(2.0e4 * 1e6, 10_000, 10_000.0, 1.5e3, 6) == pytest.approx(base)
    # one more parameter costs ln(n_eff)
    assert bic(2.0e4, 10_000, 10_000.0, 1.5, 7) - base == pytest.approx(math.log(10_000))
    # a residual at the noise floor scores ~0 in the likelihood term
    assert bic(10_000 * 1.5 ** 2, 10_000, 10_000.0, 1.5, 0) == pytest.approx(0.0, abs=1e-9)


def test_ties_go_to_the_simpler_family():
    scores = [("big", 20, 100.0), ("small", 6, 100.0 + 0.9 * TIE), ("bad", 3, 500.0)]
    assert order(scores) == ["small", "big", "bad"]
    # beyond the tie margin the data support the bigger family
    assert order([("big", 20, 100.0), ("small", 6, 100.0 + 1.1 * TIE)]) == ["big", "small"]


def _smooth_record(rng, n=8192, dt=1 / 2048):
    t = np.arange(n) * dt
    f = rng.uniform(1.0, 25.0, 3)
    angle = sum(rng.uniform(0.2, 1.0) * np.sin(2 * np.pi * fi * t + rng.uniform(0, 6)) for fi in f) * 0.01
    angle -= angle[0]  # from rest: no lead-in
    torque = 5000.0 * angle + 30.0 * np.tanh(angle / 0.004)
    return t, angle, torque


@pytest.mark.parametrize("seed", range(4))
def test_noise_floor_is_recovered_from_the_data(seed):
    """White noise on smooth random records (up to 25 Hz at 2048 Hz): the smoothing residual
    gives the noise's sigma within 5 % and no correlation."""
    rng = np.random.default_rng(seed)
    t, angle, torque = _smooth_record(rng)
    sigma = rng.uniform(0.001, 0.02) * np.abs(torque).max()
    seg = make_segment(t, angle, torque + rng.normal(0, sigma, t.size))
    noise = servo_noise([seg])
    assert noise.sigma == pytest.approx(sigma, rel=0.05)
    assert noise.lag1 < 0.05 and noise.n_eff > 0.9 * seg.compared.sum()


def _fake(n_parameters, predict):
    return SimpleNamespace(n_parameters=n_parameters, predict=predict, fit_error=Metrics(1.0, 0.01, 0.0, 1, 1.0),
                           holdout_error=None, wall_s=1.0, evaluations=1, converged=True, verdict=None)


def test_a_systematic_misfit_does_not_win_by_its_correlated_residual():
    """The previous criterion gave each family its own n_eff from its residual's lag-1
    correlation: a systematic misfit (r1 -> 1) shrank its likelihood term and ranked first.
    One n_eff from the data: the model at the noise floor ranks first, even with more
    parameters, and ties of nested families go to the simpler one."""
    rng = np.random.default_rng(3)
    t, angle, torque = _smooth_record(rng)
    sigma = 0.005 * np.abs(torque).max()
    seg = make_segment(t, angle, torque + rng.normal(0, sigma, t.size))
    truth = _fake(6, lambda segs: [torque])
    nested = _fake(20, lambda segs: [torque + 0.01 * sigma * np.sin(t)])  # the same to 1 % of the noise
    misfit = _fake(4, lambda segs: [torque + 3 * sigma * np.sin(2 * np.pi * 0.7 * t)])  # smooth: r1 ~ 1
    table = ranking_table({"misfit": misfit, "nested": nested, "truth": truth}, [seg])
    assert table["family"].tolist() == ["truth", "nested", "misfit"]
    assert table["delta_bic"].iloc[-1] > 1000
    # the same in kN*m
    seg_k = make_segment(t, angle, seg.torque_nm / 1e3)
    scaled = {k: _fake(v.n_parameters, lambda segs, p=v.predict: [p(segs)[0] / 1e3])
              for k, v in {"misfit": misfit, "nested": nested, "truth": truth}.items()}
    assert np.allclose(ranking_table(scaled, [seg_k])["bic"], table["bic"])


def test_latin_hypercube_fills_every_stratum_of_the_bounds():
    params = [FitVariable("k_nm_per_rad", 1e-2, 1e6), FitVariable("beta", 0.0, 10.0, log=False, scale=2.0)]
    rows = candidates(params, np.array([1.0, 1.0]), np.array([True, True]), 101, seed=4)
    assert np.allclose(rows[0], [1.0, 1.0])  # the first guess is a candidate
    z = np.log(rows[1:, 0])
    lo, hi = params[0].z_bounds()
    strata = np.floor((z - lo) / (hi - lo) * 100).astype(int)
    assert sorted(strata) == list(range(100))  # one candidate in each 1 % of the log range


def test_exchangeable_branches_are_ordered_by_relaxation_time():
    params = [FitVariable("a_nm_per_rad", 1, 10), FitVariable("c1_nm_per_rad", 1, 1e4), FitVariable("tau1_s", 1e-6, 1e3),
              FitVariable("c2_nm_per_rad", 1, 1e4), FitVariable("tau2_s", 1e-6, 1e3)]
    assert exchangeable_branches(params) == [[2, 1], [4, 3]]
    rows = np.array([[5.0, 100.0, 1.0, 200.0, 0.01], [5.0, 300.0, 0.001, 400.0, 0.1]])
    out = order_branches(params, rows)
    assert np.allclose(out, [[5.0, 200.0, 0.01, 100.0, 1.0], [5.0, 300.0, 0.001, 400.0, 0.1]])
    # branches that differ (another partner, other bounds) are not exchangeable
    other = params[:4] + [FitVariable("tau2_s", 1e-6, 1.0)]
    assert exchangeable_branches(other) == []


@pytest.mark.parametrize("seed", range(4))
def test_the_global_search_finds_an_oscillation_a_local_fit_misses(seed):
    """An oscillation of random frequency (15-80 Hz, the drop tower's band) over 0.2 s: least
    squares from a first guess of the frequency far off stalls in a side minimum (the amplitude
    at its lower bound); the Latin-hypercube search over the bounds finds the truth."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 0.2, 400)
    truth = np.array([rng.uniform(1.0, 3.0), rng.uniform(15.0, 80.0)])

    def residuals(rows):
        rows = np.atleast_2d(rows)
        return rows[:, [0]] * np.sin(2 * np.pi * rows[:, [1]] * t) - truth[0] * np.sin(2 * np.pi * truth[1] * t)

    params = [FitVariable("c_nm_per_rad", 1e-2, 1e2), FitVariable("f_hz", 1.0, 300.0)]
    x0, free = np.array([1.0, 200.0]), np.ones(2, bool)
    local = local_fit(FunctionProblem(params, residuals), x0, free, max_nfev=200)
    policy = SearchPolicy(starts_per_parameter=0, min_starts=256, near_share=0.0, screen_tests=None, tol=1e-7,
                          prior_weight=None, escalation=1, hop_rounds=0, loose_prior_weight=None)
    found = run_search(FunctionProblem(params, residuals), policy, x0, free, seed=seed, max_nfev=200)
    best, summary = found.fit, found.summary
    assert np.allclose(best.values, truth, rtol=1e-6)
    assert float(local.residual @ local.residual) > 100.0 and abs(local.values[1] - truth[1]) > 50.0
    assert summary["local_fits"] == 3 and summary["candidates"] == 256


def test_verdict_against_the_noise_floor_and_bounds():
    good = judge(1.2, 1.0, "nm", [])
    assert good.verdict == GOOD and good.error_over_noise == pytest.approx(1.2) and not good.reasons
    poor = judge(1.01 * NOISE_RATIO, 1.0, "nm", [])
    assert poor.verdict == POOR and "noise" in poor.reasons[0]
    # the simulation's accuracy adds to the noise in quadrature
    assert judge(NOISE_RATIO * 5.0, 3.0, "rad", [], accuracy=4.0).verdict == GOOD
    at = judge(1.0, 1.0, "nm", ["tau2_s"])
    assert at.verdict == POOR and "tau2_s" in at.reasons[0]
    assert judge(1.0, 1.0, "nm", [], converged=False).verdict == POOR
    assert set(judge(1.0, 1.0, "nm", []).to_dict()) >= {"verdict", "reasons", "noise_floor_nm", "error_over_noise"}
    params = [FitVariable("k3_gain_nm_per_rad2", 0.0, 10.0, log=False), FitVariable("tau2_s", 0.1, 10.0)]
    assert bound_hits(params, ["k3_gain_nm_per_rad2", "tau2_s"]) == ["tau2_s"]


#: For data of each family, the family most likely to beat it (the most flexible competitor,
#: or one that contains it); a family that contains the truth may tie but not win (fewer
#: parameters first).
COMPETITOR = {"zerodim6": "masing", "pfeffer": "zerodim6", "masing": "zerodim6", "elastoslide": "masing"}


@pytest.mark.slow
@pytest.mark.parametrize("kind", sorted(COMPETITOR))
def test_data_of_each_family_rank_that_family_first(kind):
    """Two random parameter sets of each family (seeded, from the benchmark's wide ranges):
    the true family ranks first against its strongest competitor (each identified as the
    command line does: the staged strategy, the global search where that fit is poor)."""
    from random_couplings import random_truth, servo_records

    from droptower.identify import identify
    from droptower.rheology import parse_coupling

    for i in range(2):
        truth = parse_coupling(random_truth(kind, np.random.default_rng(500 + i)))
        data = servo_records(truth, i)
        fits = {k: identify(k, data) for k in (kind, COMPETITOR[kind])}
        table = ranking_table(fits, data)
        assert table["family"].iloc[0] == kind, table.to_string()
        assert fits[kind].verdict.verdict == GOOD


@pytest.mark.slow
def test_a_poor_staged_start_gives_way_to_the_first_guess_and_zerodim20_follows_zerodim6():
    """zerodim6-type data (the first zerodim6 draw above) whose branch stages end far from the
    joint optimum (the slow ramps excite the fast branch too): the joint fit starts from the
    first guess instead (their costs on all data compared in one call), converges and is a good
    fit without a global search (from the staged values it used to crawl to its evaluation
    limit and end poor). zerodim20 starts from zerodim6 identified so, counts those
    evaluations, and its global search runs through zerodim6's (not over its 20 parameters)."""
    from random_couplings import random_truth, servo_records

    from droptower.identify import identify
    from droptower.rheology import parse_coupling

    truth = parse_coupling(random_truth("zerodim6", np.random.default_rng(500)))
    data = servo_records(truth, 0)
    six = identify("zerodim6", data)
    assert six.extra["joint_start"] == "first guess" and six.converged and six.verdict.verdict == GOOD
    assert "global_search" not in six.extra
    rich = identify("zerodim20", data)
    assert rich.extra["start"]["family"] == "zerodim6" and rich.extra["start"]["nrmse"] == pytest.approx(six.fit_error.nrmse)
    assert rich.evaluations > rich.extra["start"]["evaluations"] == six.evaluations
    assert rich.converged and rich.verdict.verdict == GOOD and rich.fit_error.nrmse <= six.fit_error.nrmse * (1 + 1e-9)
    # where the search goes is the claim, not what it finds: two short sweeps of the same coupling
    # at 256 Hz (2.0 s of CPU; its two sweeps of the records above at 2048 Hz, 4.1 s)
    from droptower.servo import histories as H
    from test_identify_helpers import D, records

    sweeps = {"amplitude_sweep": H.amplitude_sweep(D(np.array([0.3, 1.0, 2.5])), 8.0, 256.0, run_in_cycles=2, cycles=3),
              "frequency_sweep": H.frequency_sweep([2.0, 8.0], D(1.0), 256.0, run_in_cycles=2, cycles=3)}
    searched = identify("zerodim20", records(truth, sweeps)[0], search="always")
    assert searched.extra["global_search"]["through"] == "zerodim6" and searched.converged
