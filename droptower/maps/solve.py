"""Variable projection for the map forms: a sum of "factor × 10^(−exponent·x)" terms fitted by
NNLS for the factors on a grid of the exponents, the best grid points polished jointly with
every parameter ≥ 0, and how well the result is determined.

Shared by the paper's fit (:mod:`droptower.maps.fitting`) and the fit of any form and its term
selection (:mod:`droptower.maps.select`).
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares, nnls
# the F distribution's quantile from scipy.special (what scipy.stats.f.ppf computes): importing
# scipy.stats costs every `droptower map` about a second
from scipy.special import fdtri

from droptower.maps.forms import Equation

#: Exponent grids: a term 10^(−k·x) matters where k·x is of order 1 in the measured range,
#: so k spans 0.05/x_max … 5/x_min.
GRID_POINTS = 16
#: Best grid points polished by the nonlinear solver (multi-start).
N_POLISH = 8
#: Singular values below this fraction of the largest (column-scaled Jacobian) are treated as
#: zero: the coefficients they involve are not identifiable from the tests.
SINGULAR_RTOL = 1e-10


def exponent_grid(x: np.ndarray) -> np.ndarray:
    """Start values of a decay exponent for the multi-start search: from 0.05 / max(x) (nearly
    flat over the data) to 5 / min(x) (decayed within the smallest value), geometric."""
    return np.geomspace(0.05 / x.max(), 5.0 / x.min(), GRID_POINTS)


def relative_residuals(eq: Equation, stiffness: bool, a: np.ndarray, f: np.ndarray, target: np.ndarray):
    """Relative residuals and their Jacobian: model/c − 1 (stiffness), y/model − 1 (c/d, so
    that the damping ratio's relative error is least, as in the paper fit)."""
    if stiffness:
        return (lambda p: eq.value(p, a, f) / target - 1.0,
                lambda p: eq.jacobian(p, a, f) / target[:, None])

    def jacobian(p: np.ndarray) -> np.ndarray:
        value, jac = eq.value_and_jacobian(p, a, f)
        return -(target / value ** 2)[:, None] * jac
    return lambda p: target / eq.value(p, a, f) - 1.0, jacobian


@dataclass
class Solution:
    """One polished multi-start solution: parameters, on-bound mask, sum of squared residuals."""

    params: np.ndarray
    at_bound: np.ndarray
    ssr: float

    def permute(self, perm: list[int]) -> None:
        self.params, self.at_bound = self.params[perm], self.at_bound[perm]


def variable_projection(grid: list[tuple[int, ...]], exponents_at: Callable[[tuple[int, ...]], tuple[float, ...]],
                         basis: Callable[[tuple[int, ...]], np.ndarray], target: np.ndarray,
                         linear: tuple[int, ...], exponents: tuple[int, ...],
                         residuals: Callable[[np.ndarray], np.ndarray],
                         jacobian: Callable[[np.ndarray], np.ndarray]) -> list[Solution]:
    """Multi-start: NNLS for the linear coefficients at every grid point of the exponents
    (relative residual basis·x / target − 1); the best N_POLISH grid points that are at least
    two grid steps apart (different basins, not neighbours of one) are polished jointly.
    ``basis(ix)`` is the basis at grid point ``ix`` (exponents ``exponents_at(ix)``).
    Returns the polished solutions, best first (on-bound parameters set exactly to 0)."""
    ones = np.ones_like(target)
    scored = []
    for ix in grid:
        x, rnorm = nnls(basis(ix) / target[:, None], ones)
        scored.append((rnorm, ix, x))
    scored.sort(key=lambda s: s[0])
    starts: list[tuple[tuple[int, ...], np.ndarray]] = []
    for _, ix, x in scored:
        if all(max(abs(i - j) for i, j in zip(ix, other)) >= 2 for other, _ in starts):
            starts.append((ix, x))
            if len(starts) == N_POLISH:
                break
    solutions = []
    for ix, x in starts:
        p0 = np.empty(len(linear) + len(exponents))
        p0[list(linear)], p0[list(exponents)] = x, exponents_at(ix)
        sol = least_squares(residuals, p0, jac=jacobian, bounds=(0.0, np.inf), x_scale="jac", method="trf")
        at_bound = sol.active_mask != 0
        solutions.append(Solution(np.where(at_bound, 0.0, sol.x), at_bound, 2.0 * float(sol.cost)))
    return sorted(solutions, key=lambda s: s.ssr)


@dataclass
class Fitted:
    """The best solution of one equation and how well it is determined."""

    params: np.ndarray
    at_bound: np.ndarray
    errors: np.ndarray      # relative residuals at the tests
    std: np.ndarray         # standard uncertainties (inf: not identifiable)
    condition: float        # of the column-scaled Jacobian
    not_unique: np.ndarray  # differs between solutions inside the confidence region


def assess(solutions: list[Solution], residuals: Callable[[np.ndarray], np.ndarray],
            jacobian: Callable[[np.ndarray], np.ndarray]) -> Fitted:
    """The best of the multi-start ``solutions`` (sorted, best first) with its residuals,
    standard uncertainties, condition number and the coefficients another solution places elsewhere."""
    best = solutions[0]
    errors = residuals(best.params)
    std, condition = standard_uncertainties(jacobian(best.params), errors)
    return Fitted(best.params, best.at_bound, errors, std, condition, not_unique_coefficients(solutions, std, errors.size))


def not_unique_coefficients(solutions: list[Solution], std: np.ndarray, n: int) -> np.ndarray:
    """Coefficients that differ by more than 2 standard uncertainties between the best
    solution and another multi-start solution inside the approximate 95 % joint confidence
    region SSR ≤ SSR_best·(1 + p/(n−p)·F(p, n−p; 0.95)) (Draper & Smith, nonlinear regression)."""
    best = solutions[0]
    p = best.params.size
    limit = best.ssr * (1.0 + p / (n - p) * fdtri(p, n - p, 0.95))
    flagged = np.zeros(p, dtype=bool)
    for s in solutions[1:]:
        if s.ssr <= limit:
            flagged |= np.abs(s.params - best.params) > 2.0 * std
    return flagged


def standard_uncertainties(jac: np.ndarray, residuals: np.ndarray) -> tuple[np.ndarray, float]:
    """Standard uncertainties s·sqrt(diag((JᵀJ)⁻¹)) with s² = Σr²/(n − p), and the condition
    number of the column-scaled Jacobian; ``inf`` for coefficients in its null space."""
    n, p = jac.shape
    s2 = float(residuals @ residuals) / max(n - p, 1)
    scale = np.linalg.norm(jac, axis=0)
    scale_safe = np.where(scale > 0, scale, 1.0)
    _, sv, vt = np.linalg.svd(jac / scale_safe, full_matrices=False)
    ok = sv > SINGULAR_RTOL * sv[0]
    cov = (vt[ok].T / sv[ok] ** 2) @ vt[ok]
    std = np.sqrt(s2 * np.diag(cov)) / scale_safe
    unidentified = (scale == 0) | np.any(np.abs(vt[~ok]) > 1e-3, axis=0)
    std[unidentified] = np.inf
    cond = float(sv[0] / sv[-1]) if sv[-1] > 0 else float("inf")
    return std, cond
