"""The engine's search: Latin-hypercube multi-start over the bounds, screening, refinement, basin
moves, escalation and a loose prior, every setting declared in a :class:`SearchPolicy`.

Candidates fill the whole box of the free parameters in their optimised variables (the
logarithm of a positive parameter spanning decades, value / scale otherwise, a linear one from
0 over decades spread over them alike) as a Latin hypercube (McKay, Beckman & Conover 1979), so no decade of any parameter is left out; all
candidates of a batch are evaluated in ONE call of the residual function (the core advances
every parameter set at once). Bounded least squares (:func:`~droptower.identify.engine.local.local_fit`)
then runs from the best few distinct candidates and the lowest cost wins.

Exchangeable branches (parameters ``tau<i>_s`` with the same bounds, each with its partners
``<letter><i>_...`` of the same bounds) describe the same coupling in any order: every
candidate has them sorted by relaxation time, so the search does not spend its candidates on
copies of one coupling.

Three rules keep the search from missing the family's own optimum (each one a measured miss):

- a linear parameter from 0 over many decades (a gain, a cubic coefficient: upper bound at
  least :data:`DECADES_FROM` times its scale) is sampled where it acts: :data:`ZERO_SHARE` of
  its candidates exactly 0 (the term off), the rest log-uniform from :data:`ACTS_FROM` of its
  scale to its upper bound (a linear spread puts almost every candidate in the top decades,
  where such a term dominates the coupling); a shape parameter from 0 over a decade or two (a
  yield spread's exponent) is spread by log(1 + z) over its range;
- branches that are NOT exchangeable but whose relaxation times share their bounds (a fixed
  and a variable Maxwell branch) can play each other's role: the first guess's neighbourhood
  is sampled with the roles as guessed and swapped (:func:`role_swaps`), and the winner of the
  local fits is fitted once more with its roles swapped (a fit that put the fast relaxation on
  the wrong branch ends in a local minimum with the gain at 0, which no step of a local fit
  leaves);
- given starts (a staged strategy's result) compete with the hypercube's candidates and their
  own role-swapped copies on cost: a staged result that locked a branch out is one start
  among others, never the only one.

:func:`run_search` owns the whole loop, as lmfit's ``Minimizer`` owns its: screen the
candidates on a few clusters of the problem (:meth:`~droptower.identify.engine.problem.Problem.screening`)
-> local fits from the best (the elastoslide's odd p walked) -> the winner refined on the whole
problem (only when it beats an incumbent) -> the family's moves into neighbouring basins while
the fit is a few times its allowance -> a wider search when it is poor -> a looser prior when
it is still poor. Every setting is a field of a :class:`SearchPolicy` (the drop tests':
:data:`droptower.identify.dropfit.DROP_POLICY`; the servo records':
:data:`droptower.identify.strategies.SERVO_POLICY`); no callback decides anything. A family
contributes only the hooks its base class declares (``choices``, ``move_choice``,
``basin_moves``, ``DEFERRED``), which the problem passes on; the verdict that steers the loop
is the problem's (:meth:`~droptower.identify.engine.problem.Problem.error_over_allowance`).
"""
from __future__ import annotations

import math
import re
import warnings
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np
from scipy.stats import qmc

from droptower.identify.engine.local import LocalFit, local_fit
from droptower.identify.engine.problem import (FitVariable, FunctionProblem, Problem, clip_to_bounds,
                                               row_costs)

#: Candidates evaluated per batch (one call of the residual function each).
BATCH = 64
#: Relative tolerance of the local fits from the best candidates: they only decide which basin
#: wins; the winner is then refined to the caller's tolerance (the losers' tails, where a fit
#: creeps to its last digits, cost most of a local fit and decide nothing).
SCREEN_TOL = 1e-4
#: Half-width of the neighbourhood of the first guess sampled beside the whole box (optimised
#: variables: e^1.5 ~ 4.5 around a logarithmic parameter).
NEAR = 1.5
#: Share of the candidates of a linear parameter from 0 over decades placed at exactly 0.
ZERO_SHARE = 0.125
#: Where a linear parameter from 0 starts to act, in units of its scale: a gain of 1e-3 of the
#: data's stiffness per amplitude changes its branch by 0.1 % of the stiffness at the data's
#: amplitude.
ACTS_FROM = 1e-3
#: A linear parameter from 0 whose upper bound (over its scale) reaches this spans decades of
#: effect (a gain, a coefficient) and is sampled from :data:`ACTS_FROM`; below it (a spread
#: exponent up to 30) it is a shape parameter, spread over its range by log(1 + z).
DECADES_FROM = 100.0


def exchangeable_branches(parameters: list[FitVariable]) -> list[list[int]]:
    """Index groups, one per branch (its relaxation time first), of branches that differ only
    by their number: same parameter names apart from it and the same bounds."""
    out: dict[tuple, list[list[int]]] = {}
    for group in _branches([p.name for p in parameters]).values():
        out.setdefault(tuple(_role(parameters, j) for j in group), []).append(group)
    return [g for groups in out.values() if len(groups) > 1 for g in groups]


def _role(parameters: list[FitVariable], j: int) -> tuple:
    """What parameter ``j`` is in its branch, its branch's number aside: its name with the
    number replaced, and its bounds (two branches' parameters of one role are exchangeable)."""
    return re.sub(r"\d+", "#", parameters[j].name), parameters[j].lower, parameters[j].upper


def _branches(names: list[str]) -> dict[str, list[int]]:
    """Branch number -> [its relaxation time's index, its partners' indices]."""
    out: dict[str, list[int]] = {}
    for i, n in enumerate(names):
        m = re.fullmatch(r"tau(\d+)_s", n)
        if m:
            out[m.group(1)] = [i] + [j for j, o in enumerate(names) if j != i and not o.startswith("tau")
                                     and re.fullmatch(rf"[a-z]+{m.group(1)}_[a-z_0-9]+", o)]
    return out


def role_swaps(parameters: list[FitVariable]) -> list[list[tuple[int, int]]]:
    """Pairs of branches that are not exchangeable (other partners, e.g. a fixed and a variable
    Maxwell branch) but whose relaxation times share their bounds: per pair, the index pairs
    whose values swap to exchange their roles (the relaxation times, and the partners of the
    same name pattern and bounds, e.g. the stiffnesses; a partner without a counterpart, e.g.
    a gain, stays)."""
    names = [p.name for p in parameters]
    exchangeable = {i for g in exchangeable_branches(parameters) for i in g}
    branches = [g for g in _branches(names).values() if g[0] not in exchangeable]

    out = []
    for a in range(len(branches)):
        for b in range(a + 1, len(branches)):
            ga, gb = branches[a], branches[b]
            if _role(parameters, ga[0]) != _role(parameters, gb[0]):
                continue
            pairs = [(ga[0], gb[0])] + [(i, j) for i in ga[1:] for j in gb[1:]
                                           if _role(parameters, i) == _role(parameters, j)]
            out.append(pairs)
    return out


def swap_roles(rows: np.ndarray, swap: list[tuple[int, int]]) -> np.ndarray:
    """``rows`` (M, n) with the values of every index pair of ``swap`` exchanged."""
    rows = np.array(rows, dtype=float, copy=True)
    for i, j in swap:
        rows[..., [i, j]] = rows[..., [j, i]]
    return rows


def order_branches(parameters: list[FitVariable], rows: np.ndarray) -> np.ndarray:
    """``rows`` with every set of exchangeable branches sorted by relaxation time (ascending)."""
    groups = exchangeable_branches(parameters)
    if not groups:
        return rows
    rows = rows.copy()
    sets: dict[tuple, list[list[int]]] = {}
    for g in groups:
        sets.setdefault(tuple(re.sub(r"\d+", "#", parameters[j].name) for j in g), []).append(g)
    for gs in sets.values():
        block = np.array(gs)  # (branches, parameters per branch)
        taus = rows[:, block[:, 0]]
        perm = np.argsort(taus, axis=1)
        at = np.arange(len(rows))[:, None]
        rows[at, block.reshape(-1)[None, :]] = rows[at, block[perm].reshape(len(rows), -1)]
    return rows


def candidates(parameters: list[FitVariable], x0: np.ndarray, free: np.ndarray, n: int, seed: int = 0,
               choices: dict[int, list[float]] | None = None, near: int = 0) -> np.ndarray:
    """``n`` parameter sets (rows, physical values): ``x0`` first, then ``near`` Latin-hypercube
    points within +-:data:`NEAR` of it (clipped to the bounds), then a Latin hypercube over the
    free parameters' whole bounds, all in their optimised variables; ``choices``: parameters
    that take one of a few values (e.g. an odd exponent), drawn among them."""
    idx = np.flatnonzero(free)
    rows = np.repeat(np.asarray(x0, float)[None], n, axis=0)
    if n > 1 and idx.size:
        lo, hi = np.array([parameters[i].z_bounds() for i in idx]).T
        # the first guess's neighbourhood, with the branches' roles as guessed and swapped
        swaps = [sw for sw in role_swaps(parameters) if all(free[i] and free[j] for i, j in sw)]
        centres = [np.asarray(x0, float)] + [swap_roles(np.asarray(x0, float), sw) for sw in swaps]
        m = min(near, n - 1)
        z = np.empty((n - 1, idx.size))
        if m:
            z0 = np.array([[parameters[i].to_z(c[i]) for i in idx] for c in centres])[
                np.arange(m) * len(centres) // m]  # row r of the neighbourhood: around centre r C // m
            z[:m] = np.clip(z0 - NEAR + 2 * NEAR * qmc.LatinHypercube(d=idx.size, seed=seed + 1).random(m), lo, hi)
            # each swapped centre itself is a candidate (the first row of its share)
            for c in range(1, len(centres)):
                first = -(-c * m // len(centres))
                if first < m:
                    z[first] = [parameters[i].to_z(centres[c][i]) for i in idx]
        if n - 1 > m:
            unit = qmc.LatinHypercube(d=idx.size, seed=seed).random(n - 1 - m)
            z[m:] = lo + unit * (hi - lo)
            for k, i in enumerate(idx):
                if parameters[i].log or lo[k] != 0.0 or hi[k] <= 10.0:
                    continue
                if hi[k] >= DECADES_FROM:
                    # a linear parameter from 0 over many decades (a gain, a cubic coefficient): a
                    # share at 0 (the term off), the rest log-uniform from where it acts to its bound
                    u = np.clip((unit[:, k] - ZERO_SHARE) / (1.0 - ZERO_SHARE), 0.0, 1.0)
                    z[m:, k] = np.where(unit[:, k] < ZERO_SHARE, 0.0,
                                        ACTS_FROM * np.exp(u * np.log(hi[k] / ACTS_FROM)))
                else:
                    # a shape parameter from 0 over a decade or two (a spread exponent): spread over
                    # its range like a logarithmic one, z = expm1(u ln(1 + z_max))
                    z[m:, k] = np.expm1(unit[:, k] * np.log1p(hi[k]))
        for k, i in enumerate(idx):
            rows[1:, i] = [parameters[i].to_value(v) for v in z[:, k]]
    rng = np.random.default_rng(seed)
    for i, values in (choices or {}).items():
        rows[1:, i] = rng.choice(values, n - 1)
    rows = order_branches(parameters, rows)
    return np.array([clip_to_bounds(parameters, r) for r in rows])


def costs(residuals: Callable[[np.ndarray], np.ndarray], rows: np.ndarray, batch: int = BATCH) -> np.ndarray:
    """Sum of squared residuals of every row, ``batch`` rows per call; inf where not finite
    (candidates far out in the bounds may diverge: :func:`~droptower.identify.engine.problem.row_costs`)."""
    out = []
    for a in range(0, len(rows), batch):
        with np.errstate(all="ignore"):
            out.append(row_costs(residuals(rows[a:a + batch])))
    return np.concatenate(out)


def best_starts(parameters: list[FitVariable], rows: np.ndarray, cost: np.ndarray, keep: int,
                min_distance: float = 0.05) -> np.ndarray:
    """The ``keep`` lowest-cost rows that differ from each other by more than ``min_distance``
    of the box (in the optimised variables, largest coordinate)."""
    lo, hi = np.array([p.z_bounds() for p in parameters]).T
    span = np.where(hi > lo, hi - lo, 1.0)
    z = np.array([[p.to_z(v) for p, v in zip(parameters, r)] for r in rows]) / span
    chosen: list[int] = []
    for i in np.argsort(cost):
        if cost[i] == np.inf or len(chosen) == keep:
            break
        if all(np.max(np.abs(z[i] - z[j])) > min_distance for j in chosen):
            chosen.append(int(i))
    return rows[chosen]




# ---------------------------------------------------------------------------- the policy
@dataclass(frozen=True)
class SearchPolicy:
    """Every setting of a :func:`run_search`, declared (the defaults: the drop-test fit's).

    Attributes
    ----------
    starts_per_parameter, min_starts : int
        Latin-hypercube candidates per free parameter, at least ``min_starts``.
    near_share : float
        The share of the candidates placed around the first guess (within +-:data:`NEAR` in
        the optimised variables); the best of them is always one of the local fits' starts.
    local_fits : int
        Local fits from the best distinct candidates.
    screen_tests : int or None
        Clusters (tests) the candidates and the competing local fits run on
        (:meth:`~droptower.identify.engine.problem.Problem.screening`; None: all); the winner is
        refined on the whole problem.
    screen_tol : float
        Relative tolerance of the competing local fits (they only decide the basin).
    tol : float
        Relative tolerance of the winner's refinement and of every other fit.
    prior_weight : float or None
        Weight of a weak prior toward each local fit's start (None: no prior).
    walk_choices : bool
        The competing local fits walk a parameter of a few values (the elastoslide's odd p)
        while the cost falls (:func:`walk_choice`).
    swap_winner : bool
        The winner is fitted once more with its branches' roles swapped (:func:`role_swaps`).
    escalation : int
        A fit the problem judges poor searches again with this many times the candidates
        (other draws: seed + ``escalation_seed``, ``escalation_local_fits`` more local fits,
        the deferred parameters free); 1 or less: no second search.
    hop_range : (float, float)
        The family's moves into the basins beside a fit (``basin_moves``) run while its error
        over the allowance lies in this range.
    hop_rounds : int
        Rounds of those moves at most (0: none).
    hop_gain : float
        A further round of moves runs only where the previous one lowered the fit's cost by at
        least this fraction (a round that found a cost lower by a hair changed nothing, and
        the next one from there seldom does).
    race_nfev : int
        The moves' local fits race (:meth:`_Search.race`): each runs this many evaluations,
        the better half this many more, and only the best ``race_finalists`` run on to
        convergence (0: every move's fit runs to convergence).
    race_finalists : int
        The moves' local fits that run to convergence after the race.
    loose_prior_weight : float or None
        A fit still poor after the escalated search is fitted once more with this far weaker
        prior (None: not).
    """

    starts_per_parameter: int = 24
    min_starts: int = 96
    near_share: float = 0.25
    local_fits: int = 3
    screen_tests: int | None = 12
    screen_tol: float = SCREEN_TOL
    tol: float = 1e-6
    prior_weight: float | None = 1e-3
    walk_choices: bool = True
    swap_winner: bool = True
    escalation: int = 3
    escalation_local_fits: int = 2
    escalation_seed: int = 1000
    hop_range: tuple[float, float] = (1.0, 20.0)
    hop_rounds: int = 2
    hop_gain: float = 0.0
    race_nfev: int = 0
    race_finalists: int = 3
    loose_prior_weight: float | None = 1e-6

    def starts(self, n_free: int, escalate: bool = False) -> int:
        """Candidates of a search over ``n_free`` free parameters (the escalated one: more)."""
        return max(self.min_starts, self.starts_per_parameter * n_free) * (self.escalation if escalate else 1)


@dataclass
class SearchResult:
    """What :func:`run_search` found: the fit (without its prior's residuals), the problem it ends
    on (the whole family's, or the family's without its deferred part where that was good), the
    fit's half-step re-simulation (where the problem judges fits, else None) and the summary
    (candidates, their best cost, the local fits' costs, the role-swapped fits, hops, escalation)."""

    fit: LocalFit
    problem: Problem
    half_step: Any
    summary: dict[str, Any] = field(default_factory=dict)


# ---------------------------------------------------------------------------- the loop
def walk_choice(start: Any, choice_of: Callable[[Any], float], fit_at: Callable[[Any, float], Any],
                cost: Callable[[Any], float], candidates: list[float]) -> dict[float, Any]:
    """A parameter of a few values (the elastoslide's odd exponent p) chosen by a walk, never by
    the gradient: from the fit ``start``, over the neighbouring ``candidates`` in each direction
    while the cost falls. ``fit_at(fit, value)`` fits at that value from ``fit``; a start whose
    value is not a candidate does not walk. Returns every fit made, by its value (the caller
    keeps the cheapest)."""
    cands = sorted(candidates)
    fits = {choice_of(start): start}
    for direction in (-1, 1):
        here = start
        while True:
            old = choice_of(here)
            i = cands.index(old) + direction if old in cands else -1
            if not 0 <= i < len(cands):
                break
            new = cands[i]
            if new not in fits:
                fits[new] = fit_at(here, new)
            if cost(fits[new]) >= cost(here):
                break
            here = fits[new]
    return fits


class _Search:
    """One search's state: the policy and the fit's settings (free parameters, seed, evaluation
    limit, the parameters of a few values)."""

    def __init__(self, policy: SearchPolicy, seed: int, max_nfev: int | None, choices: dict[int, list[float]]):
        self.policy, self.seed, self.max_nfev, self.choices = policy, seed, max_nfev, choices

    def local(self, problem: Problem, start: np.ndarray, free: np.ndarray, tol: float, walk: bool = False,
              max_nfev: int | None = None) -> LocalFit:
        """A local fit with the policy's prior toward ``start``; with ``walk``, the parameters of
        a few values walked from its end (:func:`walk_choice`), the prior kept where it was;
        ``max_nfev``: evaluations at most (None: the search's limit)."""
        prior = problem if self.policy.prior_weight is None else problem.with_prior(start, free,
                                                                                     self.policy.prior_weight)
        sol = local_fit(prior, start, free, tol=tol, max_nfev=self.max_nfev if max_nfev is None else max_nfev)
        if not (walk and self.choices and self.policy.walk_choices and tol > self.policy.tol):
            return sol

        def cost(s: LocalFit) -> float:
            return s.cost if s.converged else math.inf

        for i, values in self.choices.items():
            def fit_at(here: LocalFit, value: float, i: int = i) -> LocalFit:
                x = problem.move_choice(here.values, i, value)
                return local_fit(prior, clip_to_bounds(problem.parameters, x), free, tol=tol, max_nfev=self.max_nfev)

            sol = min(walk_choice(sol, lambda s, i=i: s.values[i], fit_at, cost, values).values(), key=cost)
        return sol

    def refine(self, problem: Problem, screen: Problem, start: np.ndarray, free: np.ndarray, beat: float | None
               ) -> LocalFit | None:
        """The winner of the competing fits refined on the whole problem to the policy's
        tolerance; with an incumbent's cost ``beat`` on the screening problem, only when the
        winner beats it there (else None: a search that found nothing better does not pay a
        second refinement)."""
        if beat is not None and not float(np.sum(screen.residuals(start[None])[0] ** 2)) < beat:
            return None
        if beat is None and not self.policy.tol < self.policy.screen_tol:
            return None
        return self.local(problem, start, free, self.policy.tol)

    def global_fit(self, problem: Problem, x0: np.ndarray, free: np.ndarray, *, escalate: bool = False,
                   incumbent: np.ndarray | None = None, starts: np.ndarray | None = None
                   ) -> tuple[LocalFit | None, dict[str, Any]]:
        """Latin-hypercube candidates (the first guess, a quarter around it, the rest over the
        whole bounds; given ``starts`` and their role-swapped copies) on the screening problem,
        local fits from the best distinct ones (the best near the guess always among them), the
        winner fitted again with its roles swapped, the lowest cost refined on the whole
        problem (:meth:`refine`)."""
        policy, params = self.policy, problem.parameters
        n = policy.starts(int(free.sum()), escalate)
        screen = problem.screening(policy.screen_tests)
        beat = None if incumbent is None else float(np.sum(screen.residuals(incumbent[None])[0] ** 2))
        near = int(round(n * policy.near_share))
        choices = self.choices
        rows = candidates(params, x0, free, n, self.seed + policy.escalation_seed * escalate, choices, near)
        swaps = [sw for sw in role_swaps(params) if all(free[i] and free[j] for i, j in sw)]
        if starts is not None and len(starts):
            given = np.atleast_2d(np.asarray(starts, float))
            given = np.concatenate([given] + [swap_roles(given, sw) for sw in swaps])
            rows = np.concatenate([rows, np.array([clip_to_bounds(params, r) for r in order_branches(params, given)])])
        cost = screen.costs(rows, BATCH)
        m = 1 + min(near, n - 1)
        home = rows[[int(np.argmin(cost[:m]))]] if near else rows[:0]
        keep = policy.local_fits + policy.escalation_local_fits * escalate
        firsts = best_starts(params, np.concatenate([home, rows]), np.concatenate([[-np.inf] * len(home), cost]), keep)
        tol = max(policy.tol, policy.screen_tol)
        fits = [self.local(screen, s, free, tol, walk=True) for s in firsts]
        local_costs = [f.cost for f in fits]
        best = fits[int(np.argmin(local_costs))]
        swapped_costs = []
        if policy.swap_winner:
            for sw in swaps:
                other = self.local(screen, clip_to_bounds(params, swap_roles(best.values, sw)), free, tol, walk=True)
                swapped_costs.append(other.cost)
                if swapped_costs[-1] < best.cost:
                    best = other
        refined = self.refine(problem, screen, best.values, free, beat)
        if incumbent is not None or refined is not None:
            best = refined  # with an incumbent, None: the search found nothing better
        return best, {"candidates": int(len(rows)), "best_candidate_cost": float(np.min(cost)),
                      "local_fits": len(fits), "local_costs": local_costs, "role_swapped_costs": swapped_costs,
                      **({"search_tests": screen.n_clusters} if policy.screen_tests is not None else {})}

    def hops(self, problem: Problem, incumbent: np.ndarray | None, free: np.ndarray,
             moves: np.ndarray | None = None) -> tuple[LocalFit | None, dict]:
        """Local fits from the best distinct of the family's moves into the basins beside the
        fit ``incumbent`` (its ``basin_moves``, or ``moves``), on the screening problem; the
        lowest cost is refined on the whole problem when it beats the incumbent there (else None)."""
        params = problem.parameters
        moves = problem.basin_moves(incumbent, free) if moves is None else moves
        if not len(moves):
            return None, {"moves": 0}
        screen = problem.screening(self.policy.screen_tests)
        beat = None if incumbent is None else float(np.sum(screen.residuals(incumbent[None])[0] ** 2))
        rows = np.array([clip_to_bounds(params, r) for r in np.atleast_2d(moves)])
        cost = screen.costs(rows, BATCH)
        firsts = best_starts(params, rows, cost, len(moves), min_distance=0.0)  # distinct by construction
        summary: dict[str, Any] = {"moves": int(len(rows)), "best_move_cost": float(np.min(cost)) if len(rows)
                                   else float("inf"), "local_costs": []}
        if not len(firsts):
            return None, summary
        fits = self.race(screen, firsts, free, max(self.policy.tol, self.policy.screen_tol))
        summary["local_costs"] = [f.cost for f in fits]
        best = fits[int(np.argmin(summary["local_costs"]))]
        return self.refine(problem, screen, best.values, free, beat), summary

    def race(self, problem: Problem, starts: np.ndarray, free: np.ndarray, tol: float) -> list[LocalFit]:
        """Local fits from ``starts`` (rows), raced as successive halving (Jamieson & Talwalkar
        2016): each runs the policy's ``race_nfev`` evaluations, the better half (by cost) that
        many more, and the best ``race_finalists`` on to convergence; a fit that converged
        within its share keeps its cost, and each share after the first is a new local fit
        from where the last stopped (its prior centred there). Returns every fit, where it
        stopped (the finalists converged).

        Why: a move's local fit takes 7-60 Jacobians to converge, and the fits that lose were
        most of a round's time (masing's hard draws: 14-16 moves, 700-2000
        evaluations a round, 4-36 s); after a few steps a fit's cost mostly ranks it (both
        rounds of masing's hard draw #38 and the second of #41: the round's best fit was the
        best after three evaluations; #41's first: it overtook late, from the seventh). A fit
        that would have overtaken late is lost; the next round starts from the winner, and the
        rounds run while they gain (:meth:`hop_rounds`)."""
        nfev, finalists = self.policy.race_nfev, self.policy.race_finalists
        if not nfev or len(starts) <= finalists:
            return [self.local(problem, s, free, tol) for s in starts]
        fits = [self.local(problem, s, free, tol, max_nfev=nfev) for s in starts]

        def go_on(keep: int, max_nfev: int | None) -> None:
            order = np.argsort([f.cost for f in fits])
            for i in order[:keep]:
                if not fits[i].converged:
                    fits[i] = self.local(problem, fits[i].values, free, tol, max_nfev=max_nfev)

        go_on(max(finalists, -(-len(starts) // 2)), nfev)
        go_on(finalists, None)
        return fits

    def hop_rounds(self, problem: Problem, sol: LocalFit, half: Any, free: np.ndarray, summary: dict[str, Any]
                   ) -> tuple[LocalFit, Any, dict[str, Any]]:
        """While the fit's error over its allowance lies in the policy's ``hop_range`` and the
        last round lowered its cost by the policy's ``hop_gain`` (at most ``hop_rounds`` times),
        ``sol`` replaced by the best of :meth:`hops` where its cost is lower (else stop); the
        half-step re-simulation and the summary (its ``hops``) updated."""
        lo, hi = self.policy.hop_range
        if not self.policy.hop_rounds or not len(problem.basin_moves(sol.values, free)):
            return sol, half, summary
        before = math.inf
        for _ in range(self.policy.hop_rounds):
            ratio = problem.error_over_allowance(sol.values, half)
            if not lo < ratio < hi or not sol.cost <= (1.0 - self.policy.hop_gain) * before:
                break
            before = sol.cost
            hopped, hop = self.hops(problem, sol.values, free)
            hop = {**hop, "error_over_noise": ratio}
            summary = {**summary, "hops": summary.get("hops", []) + [hop]}
            if hopped is None:
                break
            hopped = hopped.without_prior()
            if not hopped.cost < sol.cost:
                break
            sol, half = hopped, problem.half_step(hopped.values)
            hop["taken"] = True
        return sol, half, summary


def run_search(problem: Problem, policy: SearchPolicy, x0: np.ndarray | Callable[[], np.ndarray], free: np.ndarray,
               *, seed: int = 0, max_nfev: int | None = None, first: np.ndarray | None = None,
               deferred: np.ndarray | None = None, choices: dict[int, list[float]] | None = None,
               starts: np.ndarray | None = None) -> SearchResult:
    """A global search that owns its whole loop: screen -> local fits -> refine -> the family's
    basin moves -> escalate -> loose prior, as ``policy`` declares.

    Parameters
    ----------
    problem : Problem
        The identification's problem (all fitting data).
    policy : SearchPolicy
        Every setting of the search.
    x0 : ndarray or callable
        The first guess (all parameters, their units); the fixed ones stay there. With
        ``first`` given, it may be a function that makes it: called only where the escalated
        search needs it (a family's closed-form guess can cost seconds on a large campaign).
    free : ndarray of bool
        The parameters fitted.
    seed : int
        Of the Latin hypercubes.
    max_nfev : int, optional
        Evaluation limit of every local fit (0 or None: 20 per free parameter + 20).
    first : ndarray, optional
        The first search's guess where the family defers a part (``x0`` with it off).
    deferred : ndarray of bool, optional
        Parameters of the part the first search leaves out (the problem's
        :meth:`~droptower.identify.engine.problem.Problem.without_deferred`), freed in the
        escalated search.
    choices : dict, optional
        Parameters of a few values (index -> values), drawn among them and walked.
    starts : ndarray, optional
        Further candidates (rows; e.g. a staged strategy's result).

    Returns
    -------
    SearchResult
    """
    free = np.asarray(free, bool)
    deferred = np.zeros(free.size, bool) if deferred is None else np.asarray(deferred, bool)
    run = _Search(policy, seed, max_nfev, dict(choices or {}))
    whole = problem
    if deferred.any():
        problem = problem.without_deferred()
    if first is None:
        x0 = first = x0() if callable(x0) else x0
    sol, summary = run.global_fit(problem, first, free & ~deferred, starts=starts)
    sol = sol.without_prior()
    judged = policy.hop_rounds > 0 or policy.escalation > 1 or policy.loose_prior_weight is not None
    if not judged:
        return SearchResult(sol, problem, None, summary)
    half = problem.half_step(sol.values)
    # a fit above the allowance, but not tens of times: first the family's own moves into the
    # basins beside the fit (cheaper than a wider search, and aimed where its fits are stuck)
    sol, half, summary = run.hop_rounds(problem, sol, half, free, summary)
    if deferred.any() and problem.poor(sol.values, half):
        problem = whole
        half = problem.half_step(sol.values)
    if policy.escalation > 1 and problem.poor(sol.values, half):
        # the error is many times the allowance: search again, wider (more candidates, more local
        # fits, other draws, the deferred parameters free), and keep the better fit
        wider, more = run.global_fit(problem, x0() if callable(x0) else x0, free, escalate=True, incumbent=sol.values)
        if wider is not None:
            wider = wider.without_prior()
        if wider is not None and wider.cost < sol.cost:
            sol, summary = wider, {**more, **{k: summary[k] for k in ("hops",) if k in summary}, "escalation_taken": True}
            half = problem.half_step(sol.values)
            sol, half, summary = run.hop_rounds(problem, sol, half, free, summary)
        names = [p.name for p in problem.parameters]
        summary = {**summary, "escalated": True,
                   **({"deferred_freed": [n for n, d in zip(names, deferred) if d]} if deferred.any() else {})}
    if policy.loose_prior_weight is not None and summary.get("escalated") and problem.poor(sol.values, half):
        # still poor: the prior toward each start, which pins what the data do not determine,
        # may hold a direction they determine only weakly away from the optimum (measured on
        # masing couplings of broad yield spreads): one more fit from the result with a far
        # weaker prior, kept where its error is lower
        loose = local_fit(problem, sol.values, free, prior_weight=policy.loose_prior_weight, tol=policy.tol,
                          max_nfev=max_nfev)
        if not loose.converged:
            # it crawled along a direction the data hardly determine (a slow Maxwell branch
            # against the spring b, omega tau >> 1) to its evaluation limit (measured at 0.9 x
            # the allowance, the truth's K' within 0.04 %): converged there with the usual
            # prior, centred where it ended
            loose = run.local(problem, loose.values, free, policy.tol)
        loose = loose.without_prior()
        if loose.cost < sol.cost:
            sol = loose
            half = problem.half_step(sol.values)
            summary = {**summary, "loose_prior": True}
    return SearchResult(sol, problem, half, summary)


# ---------------------------------------------------------------------------- old names
def global_fit(parameters: list[FitVariable], x0: np.ndarray, residuals: Callable[[np.ndarray], np.ndarray], *,
               free: np.ndarray, n_candidates: int, keep: int = 3, seed: int = 0, max_nfev: int | None = None,
               tol: float = 1e-7, choices: dict[int, list[float]] | None = None, near: int | None = None,
               starts: np.ndarray | None = None, swap_winner: bool = True) -> tuple[LocalFit, dict]:
    """Deprecated: :func:`run_search` on a :class:`~droptower.identify.engine.problem.FunctionProblem`
    with a :class:`SearchPolicy` (removed in the next release; its callbacks ``local``,
    ``refine`` and ``cost_of`` are gone: the policy declares what they decided)."""
    warnings.warn("droptower.identify.search.global_fit is deprecated and will be removed in the next release: use "
                  "droptower.identify.engine.run_search(FunctionProblem(parameters, residuals), SearchPolicy(...), "
                  "x0, free)", DeprecationWarning, stacklevel=2)
    policy = SearchPolicy(starts_per_parameter=0, min_starts=n_candidates, near_share=(near or 0) / n_candidates,
                          local_fits=keep, screen_tests=None,
                          tol=tol, prior_weight=None, walk_choices=False, swap_winner=swap_winner, escalation=1,
                          hop_rounds=0, loose_prior_weight=None)
    result = run_search(FunctionProblem(parameters, residuals), policy, x0, free, seed=seed, max_nfev=max_nfev,
                    choices=choices, starts=starts)
    return result.fit, result.summary


def basin_hops(parameters: list[FitVariable], moves: np.ndarray, residuals: Callable[[np.ndarray], np.ndarray], *,
               keep: int | None = None, tol: float = 1e-7, max_nfev: int | None = None) -> tuple[LocalFit | None, dict]:
    """Deprecated: the basin moves of :func:`run_search` (a family's ``basin_moves``), here from
    ``moves`` on a :class:`~droptower.identify.engine.problem.FunctionProblem` (removed in the
    next release; its callbacks ``local``, ``refine`` and ``cost_of`` are gone)."""
    warnings.warn("droptower.identify.search.basin_hops is deprecated and will be removed in the next release: the "
                  "engine's search runs a family's basin_moves", DeprecationWarning, stacklevel=2)
    del keep  # every move is fitted
    policy = SearchPolicy(screen_tests=None, tol=tol, prior_weight=None)
    free = np.ones(len(parameters), bool)
    return _Search(policy, 0, max_nfev, {}).hops(FunctionProblem(parameters, residuals), None, free,
                                                  np.atleast_2d(moves))

