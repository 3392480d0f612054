"""Nested cross-validation of the ``auto`` form: the term selection inside the validation.

``auto`` picks its terms by their cross-validated error and then reports that same error,
which is optimistic: the held-out tests took part in the choice. Here every outer fold (the
same groups as the map's cross-validation) repeats the choice without its group, by the rule
of :func:`droptower.maps.select.fit_form` (identifiable candidates first, then the least
cross-validated RMS error, the stiffness terms before the c/d terms), with ``inner_folds``
grouped folds of the remaining tests, and predicts the held-out group with the form it chose.
The error over all outer folds is what to expect of ``auto``'s map on new tests.

As in the map's own cross-validation, a fold's coefficients are refitted from the candidate's
fit to all tests (no new exponent search), and which candidates are identifiable is judged on
all tests; the errors that choose among them never see the held-out group.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from droptower.maps.forms import AUTO_RATIO_TERMS, AUTO_STIFFNESS_TERMS
from droptower.maps.select import _candidates, _rms, fit_equation, identifiable, polish

if TYPE_CHECKING:
    import pandas as pd

INNER_FOLDS = 5


@dataclass
class NestedCV:
    """Relative errors of every test predicted by the ``auto`` map chosen and fitted without
    its group; chosen: per outer fold, the (stiffness, c/d) terms chosen."""

    stiffness_errors: np.ndarray
    damping_errors: np.ndarray
    chosen: list[tuple[tuple[str, ...], tuple[str, ...]]]

    @property
    def stiffness_rms_pct(self) -> float:
        return _rms(self.stiffness_errors) * 100

    @property
    def damping_ratio_rms_pct(self) -> float:
        return _rms(self.damping_errors) * 100


def _inner_masks(groups: np.ndarray, train: np.ndarray, folds: int) -> list[np.ndarray]:
    """Training masks of the inner folds: the training groups dealt in turn to ``folds`` folds."""
    labels = np.unique(groups[train])
    k = min(folds, labels.size)
    return [train & ~np.isin(groups, labels[i::k]) for i in range(k)]


def nested_cv(a: np.ndarray, f: np.ndarray, c: np.ndarray, d: np.ndarray, groups: np.ndarray,
              inner_folds: int = INNER_FOLDS) -> NestedCV:
    """The nested cross-validation of ``auto`` (module docstring). a: amplitudes (deg),
    f: frequencies (Hz), c: stiffness (N·m/deg), d: damping ratios, groups: outer fold labels."""
    stiff_candidates = [(eq, fit_equation(eq, True, a, f, c))
                        for eq in _candidates(AUTO_STIFFNESS_TERMS, ("exp_amplitude",))]
    ratio_library = list(_candidates(AUTO_RATIO_TERMS, ("amplitude", "exp_amplitude", "exp_velocity")))
    ratio_fits: dict[tuple[str, ...], list] = {}  # per stiffness equation: every c/d candidate fitted to all tests
    errors_c, errors_d, chosen = np.empty_like(c), np.empty_like(d), []
    for g in np.unique(groups):
        train, test = groups != g, groups == g
        inner = _inner_masks(groups, train, inner_folds)

        best = None
        for eq, full in stiff_candidates:
            p = polish(eq, True, a[train], f[train], c[train], full.params)
            fold_params, err = [], []
            for fit_mask in inner:
                pi = polish(eq, True, a[fit_mask], f[fit_mask], c[fit_mask], p)
                held = train & ~fit_mask
                fold_params.append(pi)
                err.append(eq.value(pi, a[held], f[held]) / c[held] - 1.0)
            key = (not identifiable(full), _rms(np.concatenate(err)))
            if best is None or key < best[0]:
                best = (key, eq, full, p, fold_params)
        _, stiff, stiff_full, ps, stiff_folds = best

        if stiff.terms not in ratio_fits:
            y_all = stiff.value(stiff_full.params, a, f) / d
            ratio_fits[stiff.terms] = [(eq, fit_equation(eq, False, a, f, y_all)) for eq in ratio_library]
        best = None
        for eq, full in ratio_fits[stiff.terms]:
            y = stiff.value(ps, a, f) / d
            p = polish(eq, False, a[train], f[train], y[train], full.params)
            err = []
            for fit_mask, pi_s in zip(inner, stiff_folds):
                yi = stiff.value(pi_s, a, f) / d
                pi = polish(eq, False, a[fit_mask], f[fit_mask], yi[fit_mask], p)
                held = train & ~fit_mask
                err.append(stiff.value(pi_s, a[held], f[held]) / eq.value(pi, a[held], f[held]) / d[held] - 1.0)
            key = (not identifiable(full), _rms(np.concatenate(err)))
            if best is None or key < best[0]:
                best = (key, eq, p)
        _, ratio, pr = best

        errors_c[test] = stiff.value(ps, a[test], f[test]) / c[test] - 1.0
        errors_d[test] = stiff.value(ps, a[test], f[test]) / ratio.value(pr, a[test], f[test]) / d[test] - 1.0
        chosen.append((stiff.terms, ratio.terms))
    return NestedCV(errors_c, errors_d, chosen)


def chosen_summary(result: NestedCV) -> str:
    """How often each (stiffness, c/d) choice was made across the outer folds, in words."""
    counts: dict[tuple, int] = {}
    for pair in result.chosen:
        counts[pair] = counts.get(pair, 0) + 1
    return "; ".join(f"{' + '.join(s)} | {' + '.join(r)} ({n}x)"
                     for (s, r), n in sorted(counts.items(), key=lambda kv: -kv[1]))


def nested_summary(table: "pd.DataFrame", source: object = None) -> dict:
    """The nested cross-validation of ``form="auto"`` on the usable tests of a results table,
    as plain data (units in the keys): ``outer`` (how the folds were formed), ``inner_folds``,
    ``stiffness_rms_error_pct``, ``damping_ratio_rms_error_pct`` (%), ``chosen``."""
    from droptower.maps.results import REQUIRED, select_tests
    from droptower.maps.select import cv_groups

    usable = select_tests(table, source)[0]
    a, f, c, d = (usable[col].to_numpy(float) for col in REQUIRED)
    groups, method = cv_groups(usable)
    result = nested_cv(a, f, c, d, groups)
    return {"outer": method, "inner_folds": INNER_FOLDS, "stiffness_rms_error_pct": result.stiffness_rms_pct,
            "damping_ratio_rms_error_pct": result.damping_ratio_rms_pct, "chosen": chosen_summary(result)}


__all__ = ["NestedCV", "chosen_summary", "nested_cv", "nested_summary"]
