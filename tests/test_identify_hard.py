"""The global search finds its family's own optimum on hard couplings, and the verdict is right
both ways: role-swapped branches, gains sampled where they act, staged starts that compete;
a fit at the truth never "poor" (its allowance holds what the re-simulation can reach at the
logs' step), a clearly-off fit always."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from droptower.identify.data import DataScale
from droptower.identify.dropfit import DropFitSettings, DropProblem, drop_scale, drop_verdict, identify_drops, \
    servo_agreement
from droptower.identify.droplogs import ReadSettings, read_decays
from droptower.identify.families import ElastoslideFamily, MasingFamily, ZeroDim6, family_class
from droptower.identify.engine import FunctionProblem, SearchPolicy, local_fit, run_search
from droptower.identify.engine.search import ACTS_FROM, ZERO_SHARE, candidates, role_swaps, swap_roles
from droptower.identify.fit import FitVariable
from droptower.rheology import parse_coupling
from droptower.rig.config import load_rig
from droptower.rig.simulate import DropTest, simulate
from random_couplings import HARD_FAMILIES, hard_truth, truth_vector

SCALE = DataScale(0.02, 0.02, 200.0, 1e4, 1.0, 30.0)
RIG = load_rig("rapp2022")
#: the issue's plan: three levers, heights 0.1-3 m
CASES = [(0.1557, 1.0), (0.359, 2.0), (0.5233, 2.0)]
HEIGHTS = (0.1, 0.4, 1.0, 3.0)


def _decays(truth: dict, folder, duration_s: float = 0.25):
    """The issue's 12-test campaign of coupling ``truth``: noisy rig logs ``duration_s`` long after
    the impact, their decays. A shorter log than the rig's 0.25 s gives the same decays (the
    angle to the bit, the impact's rate to 1e-13) where every decay's compared window ends inside
    it (checked: at least 20 ms before its end), and costs a fraction (the rig's simulation runs
    on through the drop mass's rebounds: 12 logs of 0.15 s take 0.2 s, of 0.25 s 0.8 s)."""
    tests = [DropTest(j, m, h, 0.0, 0, 500 + 10 * a + b) for a, (j, m) in enumerate(CASES) for b, h in enumerate(HEIGHTS)]
    folder.mkdir(parents=True, exist_ok=True)
    paths = [r.write_log(folder / f"t{i}.parquet")
             for i, r in enumerate(simulate(RIG, parse_coupling(truth), tests, duration_s))]
    decays, excluded = read_decays(paths, ReadSettings())  # a double impact may exclude a test
    assert len(decays) >= 10
    assert max(d.time_s[-1] for d in decays) <= duration_s - 0.02  # no window cut by the log's end
    return decays


# ---------------------------------------------------------------------------- the search's rules
def test_fixed_and_variable_maxwell_branches_swap_roles_only_where_their_bounds_agree():
    names = [p.name for p in ZeroDim6(SCALE).parameters]
    (swap,) = role_swaps(ZeroDim6(SCALE).parameters)
    assert sorted((names[i], names[j]) for i, j in swap) == [("k2_nm_per_rad", "k3_nm_per_rad"), ("tau2_s", "tau3_s")]
    # the user confined the branches to their sides of tau_split_s: no swap
    assert role_swaps(ZeroDim6(SCALE, {"tau_split_s": 0.1}).parameters) == []
    # exchangeable branches are ordered, not swapped; single branches have nothing to swap with
    assert role_swaps(MasingFamily(SCALE).parameters) == []
    assert role_swaps(ElastoslideFamily(SCALE, {"maxwell_terms": 1}).parameters) == []
    row = np.arange(6.0)
    assert np.allclose(swap_roles(row, swap), [0, 3, 5, 1, 4, 2])  # the gain (index 4) stays


@pytest.mark.parametrize("seed", range(3))
def test_gains_are_sampled_where_they_act_and_the_swapped_guess_is_a_candidate(seed):
    fam = ZeroDim6(SCALE)
    params, x0 = fam.parameters, fam.initial()
    free = np.ones(6, bool)
    rows = candidates(params, x0, free, 801, seed=seed, near=200)
    gain = params[4]
    z = rows[201:, 4] / gain.scale  # the hypercube's part
    # 0 is pulled inside the bounds by 1e-6 of the range (trust-region-reflective starts inside)
    off = z <= 1e-6 * gain.upper / gain.scale * (1 + 1e-9)
    assert np.mean(off) == pytest.approx(ZERO_SHARE, abs=0.01)
    logs = np.log10(z[~off])
    lo, hi = math.log10(ACTS_FROM), math.log10(gain.upper / gain.scale)
    assert logs.min() >= lo - 1e-9 and logs.max() <= hi + 1e-9
    counts = np.histogram(logs, bins=int(round(hi - lo)), range=(lo, hi))[0]
    assert counts.min() > 0.7 * counts.mean()  # every decade alike
    (swap,) = role_swaps(params)
    assert any(np.allclose(r, swap_roles(x0, swap)) for r in rows[1:201])  # the guess with its roles swapped
    near = rows[1:201]
    assert 0.3 < np.mean(near[:, 2] > near[:, 5]) < 0.7  # the neighbourhood: both role assignments


def _relaxation_problem(rng):
    """A spring and two Maxwell branches, the variable one (stiffness k3 + gain a) relaxing slowly
    and the fixed one fast, seen as relaxation moduli at three amplitudes a: the closed form
    G(t, a) = k1 + k2 exp(-t / tau2) + (k3 + gain a) exp(-t / tau3)."""
    t = np.geomspace(1e-4, 1.0, 60)
    amps = np.array([0.005, 0.01, 0.02])
    tau_fast = math.exp(rng.uniform(math.log(1e-3), math.log(3e-3)))
    truth = np.array([rng.uniform(5e3, 9e3), rng.uniform(2e3, 5e3), tau_fast, rng.uniform(2e3, 5e3),
                      rng.uniform(5e4, 3e5), tau_fast * rng.uniform(5.0, 20.0)])

    def model(rows):
        rows = np.atleast_2d(rows)
        k1, k2, t2, k3, g, t3 = (rows[:, [i]] for i in range(6))
        return np.concatenate([k1 + k2 * np.exp(-t / t2) + (k3 + g * a) * np.exp(-t / t3) for a in amps], axis=1)

    def residuals(rows):
        return (model(rows) - model(truth)) / 1e3

    params = [FitVariable("k1_nm_per_rad", 1.0, 1e6), FitVariable("k2_nm_per_rad", 1.0, 1e6), FitVariable("tau2_s", 1e-6, 1e4),
              FitVariable("k3_nm_per_rad", 1.0, 1e6), FitVariable("k3_gain_nm_per_rad2", 0.0, 1e3 * 5e5, log=False, scale=5e5),
              FitVariable("tau3_s", 1e-6, 1e4)]
    return params, truth, residuals


@pytest.mark.slow
@given(seed=st.integers(0, 2 ** 16))
@settings(max_examples=12, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
def test_a_local_fit_from_the_guessed_roles_misses_the_role_swapped_truth_the_search_finds_it(seed):
    """The guess has the fixed branch slow and the variable one fast (as zerodim6's does); the
    truth the other way round. The search (near the guess only, no hypercube) recovers the
    truth's parameters through the role-swapped starts and the winner's swapped fit."""
    rng = np.random.default_rng(seed)
    params, truth, residuals = _relaxation_problem(rng)
    x0 = np.array([7e3, 3e3, 0.05, 3e3, 0.0, 2e-3])  # roles as zerodim6 guesses them: tau2 slow, tau3 fast
    free = np.ones(6, bool)
    policy = SearchPolicy(starts_per_parameter=0, min_starts=17, near_share=16 / 17, screen_tests=None, tol=1e-10,
                          prior_weight=None, escalation=1, hop_rounds=0, loose_prior_weight=None)
    found = run_search(FunctionProblem(params, residuals), policy, x0, free, seed=seed, max_nfev=400)
    best, summary = found.fit, found.summary
    assert np.allclose(best.values[[0, 1, 3]], truth[[0, 1, 3]], rtol=1e-4)
    assert np.allclose(best.values[[2, 4, 5]], truth[[2, 4, 5]], rtol=1e-4)
    assert len(summary["role_swapped_costs"]) == 1


def test_a_staged_start_that_locked_a_branch_out_competes_with_its_swapped_copy():
    """A staged result with the roles wrong (gain 0 on the fast branch) given as a start: its
    swapped copy is a candidate too, and the search ends at the truth (no hypercube)."""
    params, truth, residuals = _relaxation_problem(np.random.default_rng(3))
    locked = truth.copy()
    locked[[1, 2, 3, 5]] = truth[[3, 5, 1, 2]]
    locked[4] = 0.0
    free = np.ones(6, bool)
    alone = local_fit(FunctionProblem(params, residuals), locked, free, max_nfev=400, tol=1e-10)
    assert float(alone.residual @ alone.residual) > 1.0  # a local fit from it stays locked out
    policy = SearchPolicy(starts_per_parameter=0, min_starts=1, screen_tests=None, tol=1e-10, prior_weight=None,
                          swap_winner=False, escalation=1, hop_rounds=0, loose_prior_weight=None)
    best = run_search(FunctionProblem(params, residuals), policy, np.array([7e3, 3e3, 1e-3, 3e3, 0.0, 1e-3]), free,
                      max_nfev=400, starts=locked[None]).fit
    assert np.allclose(best.values, truth, rtol=1e-4)


# ---------------------------------------------------------------------------- the verdict at the truth
#: Log length after the impact (s) of the verdict's draws of a family where every decay's window
#: ends well before 0.15 s (measured: zerodim6's end by 0.116 s, elastoslide's by 0.119 s; masing's
#: broad spreads run to 0.21 s and keep the rig's 0.25 s).
RECORD_S = {"zerodim6": 0.15, "elastoslide": 0.15}
@pytest.mark.slow
@pytest.mark.parametrize("kind", HARD_FAMILIES)
def test_the_verdict_never_calls_the_truth_poor_and_always_calls_a_clearly_off_fit_poor(kind, tmp_path):
    """Hard draws (seeded) of each family on a 12-test campaign: the truth's own parameters are
    a good fit (the allowance holds the noise, the re-simulation's accuracy and the model's
    integration error at the logs' step), and the truth with its stiffness 3 % off or its
    relaxation / slip rate 10x off is a poor fit."""
    rng = np.random.default_rng(2700 + HARD_FAMILIES.index(kind))
    for i in range(2):
        data = hard_truth(kind, rng)
        decays = _decays(data, tmp_path / str(i), RECORD_S.get(kind, 0.25))
        fam = family_class(kind)(drop_scale(decays))
        problem = DropProblem(fam, decays, DropFitSettings())
        x = truth_vector(kind, data)
        verdict = drop_verdict(problem, x, [], True)[0]
        assert verdict.verdict == "good fit" and verdict.error_over_noise < 1.0, (data, verdict.text())
        stiff = {"zerodim6": [0, 1, 3], "elastoslide": [1, 2], "masing": [1, 2, 5, 7]}[kind]
        off = x.copy()
        off[stiff] *= 1.03
        assert drop_verdict(problem, off, [], True)[0].poor
        rate = {"zerodim6": [2, 5], "elastoslide": [3], "masing": [6, 8]}[kind]
        off = x.copy()
        off[rate] *= 10.0
        assert drop_verdict(problem, off, [], True)[0].poor


# ---------------------------------------------------------------------------- the issue's couplings
@pytest.mark.slow
def test_the_issues_six_parameter_coupling_is_found(tmp_path):
    """Spring 7000 N*m/rad, Maxwell 4000 N*m/rad with tau 2 ms, variable Maxwell 3000 N*m/rad with
    gain 5e4 N*m/rad^2 and tau 20 ms, 12 drops over three levers at 0.1-3 m: the fit used to end
    at 42 x the allowance with the gain on the wrong branch; now at the truth (K' within 1 %,
    loss factor within 3 %), a good fit, without the escalated search."""
    truth = {"element": [{"kind": "spring", "stiffness": 7000.0},
                         {"kind": "maxwell", "stiffness": 4000.0, "damping": 4000.0 * 0.002},
                         {"kind": "variable_maxwell", "stiffness": 3000.0, "stiffness_gain": 5e4,
                          "damping": 3000.0 * 0.02}]}
    decays = _decays(truth, tmp_path, 0.2)  # its decays end by 0.133 s
    result = identify_drops("zerodim6", decays)
    agree = servo_agreement(result.coupling, parse_coupling(truth), decays)
    assert agree["storage_stiffness_rms"] <= 0.01 and agree["loss_factor_rms"] <= 0.03
    assert result.verdict.verdict == "good fit" and "escalated" not in result.search
    p = result.parameters
    assert p["tau2_s"] == pytest.approx(0.002, rel=0.05) and p["tau3_s"] == pytest.approx(0.02, rel=0.05)
    assert p["k3_gain_nm_per_rad2"] == pytest.approx(5e4, rel=0.1)


@pytest.mark.slow
def test_the_issues_elastoslide_is_not_called_poor(tmp_path):
    """The elastoslide of p = 7, v_r = 0.11 rad/s, phi0 = 0.0105 (its stiffnesses drawn in the
    random range, seeded): identified within K' 1 % / loss factor 3 % and a good fit."""
    rng = np.random.default_rng(27)
    k = float(np.exp(rng.uniform(np.log(6e3), np.log(3e4))))
    truth = {"element": [{"kind": "elastoslide", "phi0": 0.0105, "k": k, "k0": k * rng.uniform(0.1, 0.5), "v_r": 0.11,
                          "p": 7, "n": 32}]}
    decays = _decays(truth, tmp_path)
    result = identify_drops("elastoslide", decays)
    agree = servo_agreement(result.coupling, parse_coupling(truth), decays)
    assert agree["storage_stiffness_rms"] <= 0.01 and agree["loss_factor_rms"] <= 0.03
    assert result.verdict.verdict == "good fit", result.verdict.text()


# ---------------------------------------------------------------------------- masing's broad spreads
@given(alpha=st.floats(0.0, 30.0), r=st.floats(1e-3, 1e3), free_r=st.booleans())
@settings(max_examples=60, deadline=None, derandomize=True)
def test_masing_moves_keep_the_full_slip_torque_and_leave_the_fits_own_exponent(alpha, r, free_r):
    """Each spread move sets alpha to one of the family's exponents (none within the gap of the
    fit's) and rescales R so that the bank's full-slip torque sum_i R e^(alpha (eta_i - 1)) is the
    fit's (closed form); the last moves scale R alone; nothing else changes; no move where R is given."""
    fam = MasingFamily(SCALE)
    v = fam.guess()
    ia, ir = fam.names.index("alpha"), fam.names.index("r_nm")
    v[ia], v[ir] = alpha, r
    free = np.ones(len(v), bool)
    free[ir] = free_r
    moves = fam.basin_moves(v, free)
    if not free_r:
        assert moves.shape == (0, len(v))
        return
    expected = [a for a in fam.MOVE_ALPHAS if abs(a - alpha) >= fam.MOVE_ALPHA_GAP]
    # last the yield limits scaled, the exponent and everything else as fitted
    moves, slips = moves[:-len(fam.MOVE_SLIP_FACTORS)], moves[-len(fam.MOVE_SLIP_FACTORS):]
    assert np.allclose(slips[:, ir], r * np.array(fam.MOVE_SLIP_FACTORS), rtol=1e-12)
    rest = np.arange(len(v)) != ir
    assert np.array_equal(slips[:, rest], np.repeat(v[None, rest], len(slips), axis=0))
    assert moves[:, ia].tolist() == expected * 2 and len(expected) >= len(fam.MOVE_ALPHAS) - 2
    eta = np.arange(7) / 6.0
    slip = moves[:, ir] * np.exp(np.outer(moves[:, ia], eta - 1.0)).sum(axis=1)
    assert np.allclose(slip, r * np.exp(alpha * (eta - 1.0)).sum(), rtol=1e-12)
    spread, slowed = moves[:len(expected)], moves[len(expected):]
    others = np.ones(len(v), bool)
    others[[ia, ir]] = False
    assert np.array_equal(spread[:, others], np.repeat(v[None, others], len(spread), axis=0))
    # the faster branch (guess: branch 2) moved to omega tau = 30, its stiffness kept; b gives
    # up the storage stiffness it gains at omega (closed form c (w tau)^2 / (1 + (w tau)^2))
    w = 2 * np.pi * SCALE.frequency_hz
    ib, ic, it = fam.names.index("b_nm_per_rad"), fam.names.index("c2_nm_per_rad"), fam.names.index("tau2_s")
    assert v[it] < v[fam.names.index("tau1_s")]
    assert np.allclose(slowed[:, it] * w, fam.MOVE_SLOW_OMEGA_TAU) and np.all(slowed[:, ic] == v[ic])
    gain = v[ic] * (900.0 / 901.0 - (w * v[it]) ** 2 / (1.0 + (w * v[it]) ** 2))
    assert np.allclose(slowed[:, ib], max(v[ib] - gain, 0.0), rtol=1e-12)
    others[[ib, it]] = False
    assert np.array_equal(slowed[:, others], np.repeat(v[None, others], len(slowed), axis=0))


def test_basin_hops_leave_a_local_minimum_a_local_fit_stays_in():
    """A cost with one local minimum per integer of x (a washboard on a parabola around
    x = 7.3): a local fit from x = 3.1 stays near 3; the hops from moves to other integers
    reach the global minimum."""
    params = [FitVariable("x", 0.0, 30.0, log=False), FitVariable("y_nm", 1e-3, 1e3)]

    def residuals(rows):
        rows = np.atleast_2d(rows)
        x, y = rows[:, 0], np.log(rows[:, 1])
        return np.stack([0.3 * (x - 7.3), 2.0 * np.sin(np.pi * (x - 7.3)), y - 1.0], axis=1)

    alone = local_fit(FunctionProblem(params, residuals), np.array([3.1, 1.0]), tol=1e-10, max_nfev=200)
    assert abs(alone.values[0] - 3.1) < 0.6
    moves = np.array([[a, 1.0] for a in (1.0, 5.0, 7.0, 11.0)])
    from droptower.identify.engine.search import basin_hops  # the old name, for one release

    with pytest.warns(DeprecationWarning, match="basin_hops is deprecated"):
        best, summary = basin_hops(params, moves, residuals, tol=1e-10, max_nfev=200)
    assert best.values[0] == pytest.approx(7.3, abs=1e-6) and best.values[1] == pytest.approx(math.e, rel=1e-6)
    assert summary["moves"] == 4 and len(summary["local_costs"]) == 4


def test_the_moves_race_keeps_the_best_basin_and_stops_the_losers_early():
    """The washboard above, a local fit from each of ten moves (one per second integer): raced
    (each fit two evaluations, the better half two more, the best two to convergence), the
    winner is the global minimum, as with every fit run to convergence, the losers stop
    unconverged, and the race costs at most 70 % of the evaluations."""
    from droptower.identify.engine.problem import Counter
    from droptower.identify.engine.search import _Search

    params = [FitVariable("x", 0.0, 30.0, log=False), FitVariable("y_nm", 1e-3, 1e3)]

    def residuals(rows):
        rows = np.atleast_2d(rows)
        x, y = rows[:, 0], np.log(rows[:, 1])
        return np.stack([0.3 * (x - 7.3), 2.0 * np.sin(np.pi * (x - 7.3)), y - 1.0], axis=1)

    moves = np.array([[a, 1.0] for a in range(1, 21, 2)], float)
    free = np.ones(2, bool)
    out = {}
    for nfev in (0, 2):
        counter = Counter()
        policy = SearchPolicy(screen_tests=None, prior_weight=None, race_nfev=nfev, race_finalists=2)
        fits = _Search(policy, 0, 200, {}).race(FunctionProblem(params, residuals, counter), moves, free, 1e-10)
        out[nfev] = fits, counter.evaluations
    (full, n_full), (raced, n_raced) = out[0], out[2]
    best = min(raced, key=lambda f: f.cost)
    assert best.values[0] == pytest.approx(7.3, abs=1e-6) and best.values[1] == pytest.approx(math.e, rel=1e-6)
    assert best.cost == pytest.approx(min(f.cost for f in full), abs=1e-12)
    assert all(f.converged for f in full) and sum(f.converged for f in raced) <= 4
    assert n_raced <= 0.7 * n_full


#: The fit the search ended in on the bench's masing hard draw #33 (a broad spread, alpha 6.5:
#: the fit at alpha 3.3 with a spurious fast Maxwell branch, 8.9 x the noise allowance; K'
#: 0.3 %, loss factor 4.1 % off), in MasingFamily's parameter order.
STUCK_33 = np.array([3634117.89, 6736.7333, 485.8473, 24.11965, 3.277203, 1703.3006, 1.0809292e-4, 3411.9793,
                     8.6762118e-3])


@pytest.mark.slow
def test_a_masing_fit_stuck_at_a_neighbouring_spread_is_moved_to_the_truths_cost(tmp_path):
    """The bench's masing hard draw #33 (seeded as there): from the fit the search ended in, a
    local fit stays poor; the hops (the spread exponent moved, :meth:`MasingFamily.basin_moves`)
    reach the truth's cost within 5 % and a good verdict."""
    from droptower.identify.dropfit import holdout_split

    rng = np.random.default_rng(27_000 + 1000 * HARD_FAMILIES.index("masing") + 33)
    data = hard_truth("masing", rng)
    decays = _decays(data, tmp_path, 0.2)  # its decays end by 0.125 s
    fam = MasingFamily(drop_scale(decays))
    problem = DropProblem(fam, [decays[i] for i in holdout_split(decays, 0.2)[0]], DropFitSettings())  # as fitted
    free = np.ones(len(fam.names), bool)
    cost = lambda v: float(np.sum(problem.residuals(v[None])[0] ** 2))  # noqa: E731
    truth = cost(truth_vector("masing", data))
    alone = local_fit(problem, STUCK_33, free, prior_weight=1e-3, tol=1e-6)
    assert cost(alone.values) > 2.0 * truth and drop_verdict(problem, alone.values, [], True)[0].poor
    with pytest.warns(DeprecationWarning, match="drop_hops is deprecated"):
        from droptower.identify.dropfit import drop_hops
    hopped, summary = drop_hops(problem, fam, STUCK_33, free, DropFitSettings())
    assert cost(hopped.values) < 1.05 * truth, summary
    assert drop_verdict(problem, hopped.values, [], True)[0].verdict == "good fit"


#: Where the first search of ``identify_drops("masing", ...)`` on the bench's masing hard draw #38
#: ended (5.7 x the allowance; the values the rounds of moves start from, to the last digit, in
#: MasingFamily's parameter order; measured with the engine whose figures
#: tests/data/regression/test_engine_regression.json stores): the global search before the rounds
#: took 4.5 s of the 17.5 s the whole fit took. The test checks the stored fit's error over the
#: allowance, so a change of the decays it is judged on shows.
FIRST_SEARCH_38 = np.array([211519.72116224776, 6969.622792698694, 1120.2981158260545, 674.0081831007623,
                            6.2948836316354395, 2124.5898035836954, 0.00012747788330336602, 3514.6026981727027,
                            0.008010220039490345])


@pytest.mark.slow
def test_masing_hard_draw_38_reaches_a_good_fit_through_raced_rounds_of_moves(tmp_path):
    """The bench's masing hard draw #38 (seeded as there; the truth at 0.22 x the allowance):
    its first search ends at 5.7 x (:data:`FIRST_SEARCH_38`); the fit's rounds of moves from there
    (the search's own stage, :meth:`_Search.hop_rounds` with the drop-test policy, as
    ``identify_drops`` runs it) take it to 4.0 x, 3.65 x, then to a good fit; two rounds left it at
    3.65 x, a false alarm. The raced rounds, four at most in the time two took, continuing while
    the cost falls by 1 %, reach a good fit, K' within 1 % and loss factor within 3 % (so the
    escalated search, which runs only on a poor fit, does not run)."""
    from droptower.identify.dropfit import DROP_POLICY, holdout_split
    from droptower.identify.engine.local import LocalFit
    from droptower.identify.engine.search import _Search

    rng = np.random.default_rng(27_000 + 1000 * HARD_FAMILIES.index("masing") + 38)
    data = hard_truth("masing", rng)
    decays = _decays(data, tmp_path, 0.15)  # its decays end by 0.113 s
    fam = MasingFamily(drop_scale(decays))
    settings = DropFitSettings()
    problem = DropProblem(fam, [decays[i] for i in holdout_split(decays, settings.holdout_fraction)[0]], settings)
    free = np.ones(len(fam.names), bool)
    residual = problem.residuals(FIRST_SEARCH_38[None])[0]
    first = LocalFit(problem.parameters, FIRST_SEARCH_38.copy(), free, residual, np.zeros((residual.size, free.sum())),
                     [], 0, 0, True, "the first search's fit, stored")
    half = problem.half_step(first.values)
    assert problem.error_over_allowance(first.values, half) == pytest.approx(5.71, abs=0.01)  # where the search left it
    rounds = _Search(DROP_POLICY, settings.seed, settings.max_nfev, {})
    sol, half, summary = rounds.hop_rounds(problem, first, half, free, {})
    assert not problem.poor(sol.values, half), summary
    assert drop_verdict(problem, sol.values, [], True)[0].verdict == "good fit"
    agree = servo_agreement(fam.coupling(sol.values), parse_coupling(data), decays)
    assert agree["storage_stiffness_rms"] <= 0.01 and agree["loss_factor_rms"] <= 0.03
    assert len(summary["hops"]) > 2 and all(h.get("taken") for h in summary["hops"])


# ---------------------------------------------------------------------------- zerodim6's near-exchangeable branches
#: Draws of ``benchmarks/bench_false_alarms.py`` (zerodim6 #22 and #58: Maxwell branches relaxing
#: within a factor 1.5 / 2.1 of each other, the gain on the faster one) and the fits the search
#: ended in, called poor at 3.7 / 2.7 x the allowance (the truth at 0.23 / 0.25 x) though K'
#: was within 0.7 % / 0.6 %: (K1, K2, tau2, K3, gain, tau3) of the truth, then of the fit.
NEAR_EXCHANGEABLE = {
    "merged": ([8074.0662, 3646.9281, 4.2522083e-3, 3042.6918, 215838.76, 2.8397299e-3],
               [6995.9516, 1137.5659, 0.62861055, 6698.9019, 70688.518, 3.4377305e-3]),
    "swapped": ([10273.640, 4490.4048, 5.5678028e-3, 2683.1735, 90115.642, 2.6272991e-3],
                [10320.133, 2408.2933, 1.5089583e-3, 5374.3541, 12981.798, 5.1465368e-3]),
}


@pytest.mark.parametrize("case", ["merged", "swapped"])
def test_a_zerodim6_fit_with_its_branches_roles_swapped_or_merged_hops_to_the_truth(case, tmp_path):
    """A 12-test campaign of each stored false alarm: from the fit the search ended in, a local
    fit stays poor; the hops (:meth:`ZeroDim6.basin_moves`: the roles exchanged, the faster branch
    split) reach a good verdict, the truth's cost within 5 % and K' within 1 %, loss factor within 3 %."""
    from droptower.identify.dropfit import holdout_split

    x_true, stuck = (np.array(v) for v in NEAR_EXCHANGEABLE[case])
    k1, k2, tau2, k3, gain, tau3 = x_true
    truth = {"element": [{"kind": "spring", "stiffness": k1}, {"kind": "maxwell", "stiffness": k2, "damping": k2 * tau2},
                         {"kind": "variable_maxwell", "stiffness": k3, "stiffness_gain": gain, "damping": k3 * tau3}]}
    decays = _decays(truth, tmp_path, 0.2)  # their decays end by 0.142 s
    fam = ZeroDim6(drop_scale(decays))
    problem = DropProblem(fam, [decays[i] for i in holdout_split(decays, 0.2)[0]], DropFitSettings())  # as fitted
    free = np.ones(6, bool)
    cost = lambda v: float(np.sum(problem.residuals(v[None])[0] ** 2))  # noqa: E731
    alone = local_fit(problem, stuck, free, prior_weight=1e-3, tol=1e-6)
    assert drop_verdict(problem, alone.values, [], True)[0].poor
    with pytest.warns(DeprecationWarning, match="drop_hops is deprecated"):
        from droptower.identify.dropfit import drop_hops
    hopped, summary = drop_hops(problem, fam, stuck, free, DropFitSettings())
    assert cost(hopped.values) < 1.05 * cost(x_true), summary
    assert drop_verdict(problem, hopped.values, [], True)[0].verdict == "good fit"
    agree = servo_agreement(fam.coupling(hopped.values), parse_coupling(truth), decays)
    assert agree["storage_stiffness_rms"] <= 0.01 and agree["loss_factor_rms"] <= 0.03
