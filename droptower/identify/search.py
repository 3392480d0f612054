"""A global search before the local least squares: Latin-hypercube multi-start over the bounds.

Candidates fill the whole box of the free parameters in their optimised variables (the
logarithm of a positive parameter spanning decades, value / scale otherwise, a linear one from
0 over decades spread over them alike) as a Latin hypercube (McKay, Beckman & Conover 1979), so no decade of any parameter is left out; all
candidates of a batch are evaluated in ONE call of the residual function (the core advances
every parameter set at once). Bounded least squares (:func:`~droptower.identify.fit.fit_rows`)
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
"""
from __future__ import annotations

import re
from typing import Any, Callable

import numpy as np
from scipy.stats import qmc

from droptower.identify.fit import FitVariable, clip_to_bounds, fit_rows, row_costs

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
    names = [p.name for p in parameters]
    branches = _branches(names)

    def signature(group: list[int]) -> tuple:
        return tuple((re.sub(r"\d+", "#", names[j]), parameters[j].lower, parameters[j].upper) for j in group)

    out: dict[tuple, list[list[int]]] = {}
    for group in branches.values():
        out.setdefault(signature(group), []).append(group)
    return [g for groups in out.values() if len(groups) > 1 for g in groups]


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

    def key(j: int) -> tuple:
        return re.sub(r"\d+", "#", names[j]), parameters[j].lower, parameters[j].upper

    out = []
    for a in range(len(branches)):
        for b in range(a + 1, len(branches)):
            ga, gb = branches[a], branches[b]
            if key(ga[0]) != key(gb[0]):
                continue
            pairs = [(ga[0], gb[0])] + [(i, j) for i in ga[1:] for j in gb[1:] if key(i) == key(j)]
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
    (candidates far out in the bounds may diverge: :func:`~droptower.identify.fit.row_costs`)."""
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


def global_fit(parameters: list[FitVariable], x0: np.ndarray, residuals: Callable[[np.ndarray], np.ndarray], *,
               free: np.ndarray, n_candidates: int, keep: int = 3, seed: int = 0, max_nfev: int | None = None,
               tol: float = 1e-7, choices: dict[int, list[float]] | None = None, near: int = 0,
               local: Callable[[np.ndarray, float], Any] | None = None,
               cost_of: Callable[[Any], float] = lambda f: float(f.residual @ f.residual),
               starts: np.ndarray | None = None, refine: Callable[[np.ndarray, float], Any] | None = None,
               swap_winner: bool = True) -> tuple[Any, dict]:
    """Latin-hypercube search over the bounds, then least squares from the ``keep`` best
    distinct candidates (``local(start, tol)``, default :func:`fit_rows` on ``residuals``) to
    the tolerance :data:`SCREEN_TOL`; the fit of lowest cost (``cost_of(fit)``) wins and is
    refined from where it ended to ``tol``. With ``near`` candidates around ``x0`` (a
    data-driven first guess), the best of those is always one of the starts: a guess whose
    basin the box's samples miss is still refined.

    ``starts`` (rows, physical values): further candidates (a staged strategy's result), which
    compete with the others, and their role-swapped copies, on cost. Where branches can swap
    roles (:func:`role_swaps`) and ``swap_winner``, the winner of the local fits is fitted again
    with its roles swapped and the lower cost wins. ``refine(start, tol)``: the winner's
    refinement to ``tol`` (default ``local``; e.g. on more data than the screening fits), run
    whenever given. Returns the fit and a summary (candidates, their best cost, the local
    fits' costs, the role-swapped fits)."""
    rows = candidates(parameters, x0, free, n_candidates, seed, choices, near)
    swaps = [sw for sw in role_swaps(parameters) if all(free[i] and free[j] for i, j in sw)]
    if starts is not None and len(starts):
        given = np.atleast_2d(np.asarray(starts, float))
        given = np.concatenate([given] + [swap_roles(given, sw) for sw in swaps])
        rows = np.concatenate([rows, np.array([clip_to_bounds(parameters, r) for r in order_branches(parameters, given)])])
    cost = costs(residuals, rows)
    m = 1 + min(near, n_candidates - 1)
    home = rows[[int(np.argmin(cost[:m]))]] if near else rows[:0]
    firsts = best_starts(parameters, np.concatenate([home, rows]), np.concatenate([[-np.inf] * len(home), cost]), keep)
    if local is None:
        def local(start: np.ndarray, tol: float) -> Any:
            return fit_rows(parameters, start, residuals, free=free, max_nfev=max_nfev, tol=tol)
    screen = max(tol, SCREEN_TOL)
    fits = [local(s, screen) for s in firsts]
    local_costs = [cost_of(f) for f in fits]
    best = fits[int(np.argmin(local_costs))]
    swapped_costs = []
    if swap_winner:
        for sw in swaps:
            other = local(clip_to_bounds(parameters, swap_roles(best.values, sw)), screen)
            swapped_costs.append(cost_of(other))
            if swapped_costs[-1] < cost_of(best):
                best = other
    if refine is not None:
        best = refine(best.values, tol)
    elif tol < SCREEN_TOL:
        best = local(best.values, tol)
    return best, {"candidates": int(len(rows)), "best_candidate_cost": float(np.min(cost)),
                  "local_fits": len(fits), "local_costs": local_costs, "role_swapped_costs": swapped_costs}


def basin_hops(parameters: list[FitVariable], moves: np.ndarray, residuals: Callable[[np.ndarray], np.ndarray], *,
               keep: int, local: Callable[[np.ndarray, float], Any],
               cost_of: Callable[[Any], float] = lambda f: float(f.residual @ f.residual),
               refine: Callable[[np.ndarray, float], Any] | None = None, tol: float = 1e-7) -> tuple[Any, dict]:
    """Local fits from the ``keep`` best distinct of ``moves`` (parameter sets a family proposes
    in other basins near a fit, e.g. a branch moved to another relaxation time), all evaluated
    in batched calls of ``residuals``; the lowest-cost fit is refined to ``tol`` (``refine``,
    default ``local``; it may return None: not worth refining). Returns the fit (or None) and
    a summary (moves, their best cost, the local fits' costs)."""
    rows = np.array([clip_to_bounds(parameters, r) for r in np.atleast_2d(moves)])
    cost = costs(residuals, rows)
    firsts = best_starts(parameters, rows, cost, keep, min_distance=0.0)  # distinct by construction
    summary = {"moves": int(len(rows)), "best_move_cost": float(np.min(cost)) if len(rows) else float("inf"),
               "local_costs": []}
    if not len(firsts):
        return None, summary
    fits = [local(s, max(tol, SCREEN_TOL)) for s in firsts]
    summary["local_costs"] = [cost_of(f) for f in fits]
    best = fits[int(np.argmin(summary["local_costs"]))]
    return (refine or local)(best.values, tol), summary
