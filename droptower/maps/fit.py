"""Fit seed 004 eq. 19 (stiffness) and eq. 20 (damping) to a table of drop tests (NOTES §1.5).

Both equations are sums of terms "coefficient × function(exponent)". For fixed exponents the
coefficients follow exactly from a non-negative linear least-squares problem (variable
projection), so the search runs over the exponents only: every combination on a log grid
scaled to the measured amplitude and frequency range is solved with NNLS, the best few are
polished with all parameters free by bounded ``scipy.optimize.least_squares`` (every
parameter ≥ 0) on relative residuals, since stiffness spans 3× over the amplitude range.

Bounds: k1, k3 ≥ 0 (the elasto-plastic Prony terms of Austrell's split are stiffnesses),
k5, k6 ≥ 0 (the viscoelastic part adds stiffness), exponents ≥ 0 (the terms decay or are
constant); so c > 0 everywhere. Eq. 20's k8, k10, k12 ≥ 0 keep c/d and thus d positive
(allowing a negative one gave the same optimum on the paper's Table 4).

Eq. 20 is fitted so that the damping ratio the map predicts, c_map(φ̂, f) / (c/d)(φ̂), matches
the measured one: the map's damping goes through its stiffness (seed 004, text after eq. 20).
"""
from __future__ import annotations

import itertools
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.optimize import least_squares, nnls
from scipy.stats import f as f_dist

from droptower.errors import DroptowerError
from droptower.maps import model
from droptower.maps.forms import FORMS, PAPER, MapForm
from droptower.maps.mapfit import FitStats, MapFit, MapRange
from droptower.maps.results import REQUIRED, ExcludedTest, read_results, select_tests

#: Eq. 19 has 7 coefficients; 3 tests more leave 3 degrees of freedom for the residual
#: variance from which the uncertainties are scaled.
MIN_TESTS = len(model.STIFFNESS_UNITS) + 3
#: Eq. 19 needs at least 3 distinct amplitudes and 3 distinct frequencies (values closer than
#: 1 % count as one) to separate the amplitude terms from the frequency terms.
MIN_LEVELS = 3
LEVEL_RTOL = 0.01
#: Exponent grids: a term 10^(−k·x) matters where k·x is of order 1 in the measured range,
#: so k spans 0.05/x_max … 5/x_min (plus 0, a constant term, where that is a separate shape).
GRID_POINTS = 16
#: Best grid points polished by the nonlinear solver (multi-start).
N_POLISH = 8
#: Singular values below this fraction of the largest (column-scaled Jacobian) are treated as
#: zero: the coefficients they involve are not identifiable from the tests.
SINGULAR_RTOL = 1e-10


def fit_map(results: pd.DataFrame | str | Path, source: str | Path | None = None,
            form: str | MapForm = "paper") -> MapFit:
    """Fit eq. 19 and eq. 20 (``form="paper"``), another form (a name of :data:`droptower.maps.forms.FORMS` or a
    :class:`~droptower.maps.forms.MapForm`),
    or the terms chosen by cross-validation (``"auto"``, :mod:`droptower.maps.select`) to a
    results table (DataFrame, or a CSV/Parquet path); every form is cross-validated.

    Columns: ``amplitude_deg``, ``frequency_hz``, ``stiffness_nm_per_deg``, ``damping_ratio``
    (optional ``flags``, ``file``, ``drop_height_m``). Flagged, incomplete or non-positive tests are excluded and
    listed in the result. Too few tests or a degenerate design (fewer than 3 distinct
    amplitudes or frequencies) is a one-line :class:`DroptowerError` naming ``source``.
    """
    from droptower.maps import select  # select builds on this module's solver

    if isinstance(form, str) and form != "auto" and form not in FORMS:
        raise DroptowerError(f"unknown map form {form!r} (use {', '.join([*FORMS, 'auto'])})", file=source)
    if not isinstance(results, pd.DataFrame):
        source = results if source is None else source
        results = read_results(results)
    usable, excluded = select_tests(results, source)
    a, f, c, d = (usable[col].to_numpy(float) for col in REQUIRED)
    _check_design(a, f, excluded, source)
    groups, cv_method = select.cv_groups(usable)

    if form == "paper":
        s19 = _fit_stiffness(a, f, c)
        y = model.stiffness(s19.params, a, f) / d  # eq. 20's target: the c/d that makes the map's damping ratio match
        fitted = select.fit_form(PAPER, a, f, c, d, groups, cv_method, s19, _fit_ratio(a, y))
    else:
        chosen = form if isinstance(form, MapForm) else None if form == "auto" else FORMS[form]
        fitted = select.fit_form(chosen, a, f, c, d, groups, cv_method)
    s19, s20 = fitted.stiffness, fitted.ratio

    names = [*fitted.form.stiffness_names, *fitted.form.ratio_names]
    both = {key: np.concatenate([getattr(s19, key), getattr(s20, key)]) for key in ("params", "std", "at_bound", "not_unique")}
    return MapFit(
        coefficients=dict(zip(names, map(float, both["params"]))),
        uncertainties=dict(zip(names, map(float, both["std"]))),
        stats=FitStats(
            n_tests=int(a.size),
            stiffness_rms_error_pct=_rms(s19.errors) * 100, stiffness_max_error_pct=float(np.max(np.abs(s19.errors))) * 100,
            damping_ratio_rms_error_pct=_rms(s20.errors) * 100, damping_ratio_max_error_pct=float(np.max(np.abs(s20.errors))) * 100,
            stiffness_condition_number=s19.condition, damping_condition_number=s20.condition,
            stiffness_cv_rms_error_pct=_rms(fitted.stiffness_cv_errors) * 100,
            damping_ratio_cv_rms_error_pct=_rms(fitted.damping_cv_errors) * 100,
        ),
        range=MapRange.of_points(a, f),
        excluded=excluded,
        at_bounds=tuple(n for n, flag in zip(names, both["at_bound"]) if flag),
        not_unique=tuple(n for n, flag in zip(names, both["not_unique"]) if flag),
        source=str(source) if source is not None else None,
        form=fitted.form,
        cross_validation=cv_method,
    )


def _check_design(a: np.ndarray, f: np.ndarray, excluded: list[ExcludedTest], source: str | Path | None) -> None:
    """Enough tests, spread over enough amplitudes and frequencies, or a one-line error."""
    if a.size < MIN_TESTS:
        reasons = Counter(r for e in excluded for r in e.reason.split("; "))
        why = ", ".join(f"{r} ×{n}" for r, n in reasons.most_common(3))
        raise DroptowerError(
            f"only {a.size} usable tests ({len(excluded)} excluded{': ' + why if why else ''}); "
            f"eq. 19 has {len(model.STIFFNESS_UNITS)} coefficients, a map needs at least {MIN_TESTS} tests",
            file=source)
    for one, many, x, unit in (("frequency", "frequencies", f, "Hz"), ("amplitude", "amplitudes", a, "deg")):
        n = _levels(x)
        if n < MIN_LEVELS:
            values = ", ".join(f"{v:.4g}" for v in np.unique(np.round(x, 3))[:5])
            raise DroptowerError(
                f"degenerate tests: {f'all at one {one}' if n == 1 else f'only {n} distinct {many}'} "
                f"({values} {unit}); eq. 19 needs tests at {MIN_LEVELS} or more distinct {many}", file=source)


def _levels(x: np.ndarray) -> int:
    """Number of distinct levels: a level takes every value within LEVEL_RTOL above its lowest
    value (greedy from the smallest, so a dense spread of values still counts as many levels)."""
    count, start = 0, -np.inf
    for v in np.sort(x):
        if v > start * (1 + LEVEL_RTOL):
            count, start = count + 1, v
    return count


def _grid(x: np.ndarray) -> np.ndarray:
    return np.geomspace(0.05 / x.max(), 5.0 / x.min(), GRID_POINTS)


def _fit_stiffness(a: np.ndarray, f: np.ndarray, c: np.ndarray) -> _Fitted:
    """Eq. 19 on relative residuals c_map / c − 1 (k1..k7)."""
    ga, gf = _grid(a), np.array([0.0, *_grid(f)])
    # k2 < k4: the two Prony terms are interchangeable
    grid = [(i, j, k) for i, j in itertools.combinations(range(ga.size), 2) for k in range(gf.size)]

    def residuals(p: np.ndarray) -> np.ndarray:
        return model.stiffness(p, a, f) / c - 1.0

    def jacobian(p: np.ndarray) -> np.ndarray:
        return model.stiffness_jacobian(p, a, f) / c[:, None]

    solutions = _variable_projection(
        grid, lambda ix: (ga[ix[0]], ga[ix[1]], gf[ix[2]]), lambda e: model.stiffness_basis(e, a, f), c,
        model.STIFFNESS_LINEAR, model.STIFFNESS_EXPONENTS, residuals, jacobian)
    for s in solutions:  # slow Prony term first, so the result is unique
        if s.params[1] > s.params[3]:
            s.permute([2, 3, 0, 1, 4, 5, 6])
    return _assess(solutions, residuals, jacobian)


def _fit_ratio(a: np.ndarray, y: np.ndarray) -> _Fitted:
    """Eq. 20 so that y / (c/d) − 1, the damping ratio's relative error, is least (k8..k13)."""
    g = np.array([0.0, *_grid(a)])
    grid = list(itertools.combinations(range(g.size), 3))

    def residuals(p: np.ndarray) -> np.ndarray:
        return y / model.stiffness_over_damping(p, a) - 1.0

    def jacobian(p: np.ndarray) -> np.ndarray:
        return -(y / model.stiffness_over_damping(p, a) ** 2)[:, None] * model.ratio_jacobian(p, a)

    solutions = _variable_projection(grid, lambda ix: tuple(g[list(ix)]), lambda e: model.ratio_basis(e, a), y,
                                     model.RATIO_LINEAR, model.RATIO_EXPONENTS, residuals, jacobian)
    for s in solutions:  # terms by increasing exponent
        order = np.argsort(s.params[list(model.RATIO_EXPONENTS)], kind="stable")
        s.permute([j for i in order for j in (2 * i, 2 * i + 1)])
    return _assess(solutions, residuals, jacobian)


@dataclass
class _Solution:
    """One polished multi-start solution: parameters, on-bound mask, sum of squared residuals."""

    params: np.ndarray
    at_bound: np.ndarray
    ssr: float

    def permute(self, perm: list[int]) -> None:
        self.params, self.at_bound = self.params[perm], self.at_bound[perm]


def _variable_projection(grid: list[tuple[int, ...]], exponents_at: Callable[[tuple[int, ...]], tuple[float, ...]],
                         basis: Callable[[tuple[float, ...]], np.ndarray], target: np.ndarray,
                         linear: tuple[int, ...], exponents: tuple[int, ...],
                         residuals: Callable[[np.ndarray], np.ndarray],
                         jacobian: Callable[[np.ndarray], np.ndarray]) -> list[_Solution]:
    """Multi-start: NNLS for the linear coefficients at every grid point of the exponents
    (relative residual basis·x / target − 1); the best N_POLISH grid points that are at least
    two grid steps apart (different basins, not neighbours of one) are polished jointly.
    Returns the polished solutions, best first (on-bound parameters set exactly to 0)."""
    ones = np.ones_like(target)
    scored = []
    for ix in grid:
        x, rnorm = nnls(basis(exponents_at(ix)) / target[:, None], ones)
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
        solutions.append(_Solution(np.where(at_bound, 0.0, sol.x), at_bound, 2.0 * float(sol.cost)))
    return sorted(solutions, key=lambda s: s.ssr)


@dataclass
class _Fitted:
    """The best solution of one equation and how well it is determined."""

    params: np.ndarray
    at_bound: np.ndarray
    errors: np.ndarray      # relative residuals at the tests
    std: np.ndarray         # standard uncertainties (inf: not identifiable)
    condition: float        # of the column-scaled Jacobian
    not_unique: np.ndarray  # differs between solutions inside the confidence region


def _assess(solutions: list[_Solution], residuals: Callable[[np.ndarray], np.ndarray],
            jacobian: Callable[[np.ndarray], np.ndarray]) -> _Fitted:
    best = solutions[0]
    errors = residuals(best.params)
    std, condition = _standard_uncertainties(jacobian(best.params), errors)
    return _Fitted(best.params, best.at_bound, errors, std, condition, _not_unique(solutions, std, errors.size))


def _not_unique(solutions: list[_Solution], std: np.ndarray, n: int) -> np.ndarray:
    """Coefficients that differ by more than 2 standard uncertainties between the best
    solution and another multi-start solution inside the approximate 95 % joint confidence
    region SSR ≤ SSR_best·(1 + p/(n−p)·F(p, n−p; 0.95)) (Draper & Smith, nonlinear regression)."""
    best = solutions[0]
    p = best.params.size
    limit = best.ssr * (1.0 + p / (n - p) * f_dist.ppf(0.95, p, n - p))
    flagged = np.zeros(p, dtype=bool)
    for s in solutions[1:]:
        if s.ssr <= limit:
            flagged |= np.abs(s.params - best.params) > 2.0 * std
    return flagged


def _standard_uncertainties(jac: np.ndarray, residuals: np.ndarray) -> tuple[np.ndarray, float]:
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


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x**2)))
