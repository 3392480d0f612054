"""Fit a map form, by default Rapp et al. 2022, eq. 19 (stiffness) and eq. 20 (damping), to a
table of drop tests.

Every form, the paper's included, goes the same way (:func:`droptower.maps.select.fit_form`,
the solver in :mod:`droptower.maps.solve`). Both equations are sums of terms "coefficient × function(exponent)". For fixed exponents the
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
the measured one: the map's damping goes through its stiffness (Rapp et al. 2022, text after eq. 20).
"""
from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np
import pandas as pd

from droptower.errors import DroptowerError
from droptower.maps import select
from droptower.maps.forms import FORMS, PAPER, MapForm
from droptower.maps.mapfit import FitStats, MapFit, MapRange
from droptower.maps.results import REQUIRED, ExcludedTest, read_results, select_tests

#: Eq. 19 has 7 coefficients; 3 tests more leave 3 degrees of freedom for the residual
#: variance from which the uncertainties are scaled.
MIN_TESTS = PAPER.stiffness.size + 3
#: Eq. 19 needs at least 3 distinct amplitudes and 3 distinct frequencies (values closer than
#: 1 % count as one) to separate the amplitude terms from the frequency terms.
MIN_LEVELS = 3
LEVEL_RTOL = 0.01


def fit_map(results: pd.DataFrame | str | Path, source: str | Path | None = None,
            form: str | MapForm = "paper") -> MapFit:
    """Fit the characteristic map (Rapp et al. 2022, eq. 19-20, or another form) to drop tests.

    Parameters
    ----------
    results : DataFrame, str or Path
        The results table (or a path :func:`read_results` reads): ``amplitude_deg``,
        ``frequency_hz``, ``stiffness_nm_per_deg`` (N·m/deg), ``damping_ratio`` (optional
        ``flags``, ``file``, ``drop_height_m``). Flagged, incomplete or non-positive tests are
        excluded and listed in the result.
    source : str or Path, optional
        What the errors and the summary call the table (default: the path given).
    form : str or MapForm, default "paper"
        ``"paper"`` (eq. 19 and eq. 20), another form (a name of
        :data:`droptower.maps.forms.FORMS` or a :class:`~droptower.maps.forms.MapForm`), or
        ``"auto"``: the terms chosen by cross-validation (:mod:`droptower.maps.select`).

    Returns
    -------
    MapFit
        The coefficients with their uncertainties, the fit's and the cross-validated errors;
        ``stiffness_nm_per_deg(a, f)`` and ``damping_ratio(a, f)`` predict (degrees, Hz).

    Raises
    ------
    DroptowerError
        Too few tests or a degenerate design (fewer than 3 distinct amplitudes or frequencies),
        naming ``source``.
    """
    if isinstance(form, str) and form != "auto" and form not in FORMS:
        raise DroptowerError(f"unknown map form {form!r} (use {', '.join([*FORMS, 'auto'])})", file=source)
    if not isinstance(results, pd.DataFrame):
        source = results if source is None else source
        results = read_results(results)
    usable, excluded = select_tests(results, source)
    a, f, c, d = (usable[col].to_numpy(float) for col in REQUIRED)
    _check_design(a, f, excluded, source)
    groups, cv_method = select.cv_groups(usable)

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
        fixtures=_fixtures(usable),
        temperature_range_c=_temperatures(usable),
    )


def _fixtures(usable: pd.DataFrame) -> tuple[str, ...]:
    """The lever fixtures of the tests used: their names, else their inertias (kg*m^2)."""
    named = sorted({str(v).strip() for v in usable["fixture"].dropna()} - {""}) if "fixture" in usable.columns else []
    if named:
        return tuple(named)
    if "inertia_kgm2" in usable.columns:
        j = pd.to_numeric(usable["inertia_kgm2"], errors="coerce").dropna().unique()
        return tuple(f"{v:g} kg*m^2" for v in sorted(j))
    return ()


def _temperatures(usable: pd.DataFrame) -> tuple[float, float] | None:
    """(min, max) of the tests' ``temperature_c`` (degC), None without temperatures."""
    if "temperature_c" not in usable.columns:
        return None
    t = pd.to_numeric(usable["temperature_c"], errors="coerce").dropna()
    return (float(t.min()), float(t.max())) if len(t) else None


def _check_design(a: np.ndarray, f: np.ndarray, excluded: list[ExcludedTest], source: str | Path | None) -> None:
    """Enough tests, spread over enough amplitudes and frequencies, or a one-line error."""
    if a.size < MIN_TESTS:
        reasons = Counter(r for e in excluded for r in e.reason.split("; "))
        why = ", ".join(f"{r} ×{n}" for r, n in reasons.most_common(3))
        raise DroptowerError(
            f"only {a.size} usable tests ({len(excluded)} excluded{': ' + why if why else ''}); "
            f"eq. 19 has {PAPER.stiffness.size} coefficients, a map needs at least {MIN_TESTS} tests",
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


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x**2)))
