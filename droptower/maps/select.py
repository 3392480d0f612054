"""Fit any :class:`~droptower.maps.forms.MapForm`, cross-validate it, and choose the terms.

Fitting is the variable projection of :mod:`droptower.maps.solve`: NNLS for the
factors on a grid of the exponents, the best grid points polished jointly with every parameter
≥ 0. Cross-validation refits both equations without each group of tests, warm-started from the
full fit, and predicts the group left out: leave-one-drop-height-out when the table has drop
heights (a height is one amplitude level per case: leaving it out asks the map to interpolate
between levels, as it is used), else leave-one-out. ``auto`` fits every sub-multiset of
:data:`~droptower.maps.forms.AUTO_STIFFNESS_TERMS` and then of
:data:`~droptower.maps.forms.AUTO_RATIO_TERMS` and keeps, of the candidates whose every
coefficient is identifiable (none on its bound, finite uncertainty below half its value, not
moved by another equally good solution), the one with the least cross-validated RMS error; so
terms the data do not pin down are pruned, not reported.
"""
from __future__ import annotations

import itertools
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.optimize import least_squares

from droptower.maps.forms import AUTO_RATIO_TERMS, AUTO_STIFFNESS_TERMS, KINDS, Equation, MapForm
from droptower.maps.solve import Fitted, assess, exponent_grid, relative_residuals, variable_projection

#: An uncertainty above this fraction of its coefficient counts as not identified (the
#: summary's "poorly identified" line uses the same).
MAX_RELATIVE_STD = 0.5
#: Candidates of ``auto`` have at most as many parameters per equation as eq. 19 (7): more
#: cannot be identified from a campaign of a few cases, and the search grows with each term.
MAX_PARAMETERS = 7
#: Tests whose drop heights agree within this are one cross-validation group.
HEIGHT_DECIMALS = 6


def _exponent_grids(eq: Equation, a: np.ndarray, f: np.ndarray) -> tuple[list[tuple[int, ...]], list[np.ndarray]]:
    """Grid index tuples over the equation's exponents and the grid of each exponent term.

    Terms of one kind take increasing grid points (they are interchangeable), so no
    permutation of one solution is searched twice."""
    grids = {"exp_amplitude": exponent_grid(a), "exp_frequency": exponent_grid(f),
             "exp_velocity": exponent_grid(a * f)}
    kinds = [t for t in eq.terms if KINDS[t][1] is not None]
    per_kind = {k: [i for i, t in enumerate(kinds) if t == k] for k in dict.fromkeys(kinds)}
    points = []
    for combo in itertools.product(*(itertools.combinations(range(len(grids[k])), len(ix)) for k, ix in per_kind.items())):
        ix = [0] * len(kinds)
        for positions, values in zip(per_kind.values(), combo):
            for p, v in zip(positions, values):
                ix[p] = v
        points.append(tuple(ix))
    return points, [grids[k] for k in kinds]


def fit_equation(eq: Equation, stiffness: bool, a: np.ndarray, f: np.ndarray, target: np.ndarray) -> Fitted:
    """Fit one equation to ``target`` (c, or y = c_map/d for c/d) by variable projection."""
    points, grids = _exponent_grids(eq, a, f)
    residuals, jacobian = relative_residuals(eq, stiffness, a, f, target)
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):  # far trial steps of the solver; their residual is inf, rejected
        solutions = variable_projection(
            points, lambda ix: tuple(g[i] for g, i in zip(grids, ix)), eq.basis_on_grid(grids, a, f), target,
            eq.linear, eq.exponents, residuals, jacobian)
    for s in solutions:  # terms of one kind by increasing exponent, so the names are unique
        s.permute(_canonical_order(eq, s.params))
    return assess(solutions, residuals, jacobian)


def _canonical_order(eq: Equation, params: np.ndarray) -> list[int]:
    starts = [*eq.linear, eq.size]
    slots = [list(range(starts[i], starts[i + 1])) for i in range(len(eq.terms))]
    order = list(range(len(eq.terms)))
    for kind in set(eq.terms):
        same = [i for i, t in enumerate(eq.terms) if t == kind]
        if KINDS[kind][1] is not None and len(same) > 1:
            for i, j in zip(same, sorted(same, key=lambda i: params[slots[i][1]])):
                order[i] = j
    return [p for i in order for p in slots[i]]


def polish(eq: Equation, stiffness: bool, a: np.ndarray, f: np.ndarray, target: np.ndarray, p0: np.ndarray) -> np.ndarray:
    """Refit one equation from ``p0`` (a fold of the cross-validation: no new search)."""
    residuals, jacobian = relative_residuals(eq, stiffness, a, f, target)
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        return least_squares(residuals, p0, jac=jacobian, bounds=(0.0, np.inf), x_scale="jac", method="trf").x


def identifiable(fitted: Fitted) -> bool:
    """Every coefficient off its bound, unique, with a finite uncertainty below
    :data:`MAX_RELATIVE_STD` of its value."""
    return bool(not fitted.at_bound.any() and not fitted.not_unique.any()
                and np.all(fitted.std <= MAX_RELATIVE_STD * np.abs(fitted.params)))


def cv_groups(tests: pd.DataFrame) -> tuple[np.ndarray, str]:
    """Group label per test and the method's name: by drop height if there are 3 or more
    heights, else one test per group (leave-one-out)."""
    if "drop_height_m" in tests.columns:
        h = pd.to_numeric(tests["drop_height_m"], errors="coerce").round(HEIGHT_DECIMALS)
        if h.notna().all() and h.nunique() >= 3:
            return h.to_numpy(), f"leave-one-drop-height-out ({h.nunique()} folds)"
    return np.arange(len(tests)), f"leave-one-out ({len(tests)} folds)"


@dataclass
class _Folds:
    """The stiffness equation refitted without each group: the training masks and the
    parameters, shared by every c/d candidate."""

    train: list[np.ndarray]
    stiffness: list[np.ndarray]


def _stiffness_folds(eq: Equation, params: np.ndarray, a: np.ndarray, f: np.ndarray, c: np.ndarray,
                     groups: np.ndarray) -> tuple[_Folds, np.ndarray]:
    """Refit the stiffness per fold; returns the folds and the cross-validated relative errors."""
    folds, errors = _Folds([], []), np.empty_like(c)
    for g in np.unique(groups):
        train = groups != g
        p = polish(eq, True, a[train], f[train], c[train], params)
        errors[~train] = eq.value(p, a[~train], f[~train]) / c[~train] - 1.0
        folds.train.append(train)
        folds.stiffness.append(p)
    return folds, errors


def _ratio_cv(stiff: Equation, eq: Equation, params: np.ndarray, folds: _Folds,
              a: np.ndarray, f: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Cross-validated relative errors of the damping ratio with c/d ``eq``."""
    errors = np.empty_like(d)
    for train, ps in zip(folds.train, folds.stiffness):
        y = stiff.value(ps, a, f) / d
        p = polish(eq, False, a[train], f[train], y[train], params)
        test = ~train
        errors[test] = stiff.value(ps, a[test], f[test]) / eq.value(p, a[test], f[test]) / d[test] - 1.0
    return errors


@dataclass
class FormFit:
    """A form fitted to the tests, with fit and cross-validated relative errors."""

    form: MapForm
    stiffness: Fitted
    ratio: Fitted
    stiffness_cv_errors: np.ndarray
    damping_cv_errors: np.ndarray
    cv_method: str


def _candidates(library: tuple[str, ...], need: tuple[str, ...]) -> Iterator[Equation]:
    """Every sub-multiset of ``library`` (in library order) holding a term of a kind in
    ``need``, with at most :data:`MAX_PARAMETERS` parameters."""
    seen = set()
    for r in range(1, len(library) + 1):
        for terms in itertools.combinations(library, r):
            if terms not in seen and any(t in need for t in terms) and Equation(terms).size <= MAX_PARAMETERS:
                seen.add(terms)
                yield Equation(terms)


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x**2)))


def fit_form(form: MapForm | None, a: np.ndarray, f: np.ndarray, c: np.ndarray, d: np.ndarray,
             groups: np.ndarray, cv_method: str) -> FormFit:
    """Fit ``form`` (``None``: choose the terms, ``auto``) and cross-validate it."""
    if form is None:
        return _auto(a, f, c, d, groups, cv_method)
    s = fit_equation(form.stiffness, True, a, f, c)
    r = fit_equation(form.ratio, False, a, f, form.stiffness.value(s.params, a, f) / d)
    folds, cv_c = _stiffness_folds(form.stiffness, s.params, a, f, c, groups)
    cv_d = _ratio_cv(form.stiffness, form.ratio, r.params, folds, a, f, d)
    return FormFit(form, s, r, cv_c, cv_d, cv_method)


def _auto(a: np.ndarray, f: np.ndarray, c: np.ndarray, d: np.ndarray, groups: np.ndarray, cv_method: str) -> FormFit:
    """Choose the stiffness terms, then the c/d terms, by cross-validated RMS error among the
    identifiable candidates (all candidates if none is)."""
    best = None
    for eq in _candidates(AUTO_STIFFNESS_TERMS, ("exp_amplitude",)):
        fitted = fit_equation(eq, True, a, f, c)
        folds, cv = _stiffness_folds(eq, fitted.params, a, f, c, groups)
        key = (not identifiable(fitted), _rms(cv))
        if best is None or key < best[0]:
            best = (key, eq, fitted, folds, cv)
    _, stiff, s, folds, cv_c = best
    y = stiff.value(s.params, a, f) / d
    best = None
    for eq in _candidates(AUTO_RATIO_TERMS, ("amplitude", "exp_amplitude", "exp_velocity")):
        fitted = fit_equation(eq, False, a, f, y)
        cv = _ratio_cv(stiff, eq, fitted.params, folds, a, f, d)
        key = (not identifiable(fitted), _rms(cv))
        if best is None or key < best[0]:
            best = (key, eq, fitted, cv)
    _, ratio_eq, r, cv_d = best
    return FormFit(MapForm("auto", stiff, ratio_eq), s, r, cv_c, cv_d, cv_method)
