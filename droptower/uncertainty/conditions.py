"""The uncertainty budget of each condition's mean (a campaign's results table: one row per
test): which input dominates the stiffness, the damping ratio, the amplitude and the frequency
of a condition (GUM, JCGM 100:2008; docs/guide/uncertainty.md#budget-per-condition).

First order on the table alone, by the measurement model's closed forms
(:mod:`droptower.uncertainty.model`), relative contributions:

- the repeats (type A): the standard deviation of the condition's tests over √n (n ≥ 2), else
  the one test's fit uncertainty (``*_std``);
- the lever inertia: u_J/J of the condition's fixture on the stiffness (c = J(ω² + δ²));
- the sample clock: u_fs/fs on the frequency, twice it on the stiffness (ω, δ ∝ f_s);
- the laser's radius and calibration: u_r/r and u_κ on the amplitude (φ ∝ 1/(r·κ_L));
- the damping ratio carries none of them (δ/ω).

The inputs are shared by every test of the condition, so they do not shrink with n.
"""
from __future__ import annotations

import math

import numpy as np
import pandas as pd

from droptower.errors import DroptowerError, expects
from droptower.rig.uncertainty import RigUncertainty
from droptower.uncertainty.budget import COVERAGE_FACTOR

#: the columns that name a condition (those present are used)
CONDITION_COLUMNS: tuple[str, ...] = ("fixture", "inertia_kgm2", "drop_mass_kg", "drop_height_m", "preload_nm")
#: the quantities of a condition's budget (the results table's columns, with ``<q>_std``)
BUDGET_QUANTITIES: tuple[str, ...] = ("stiffness_nm_per_deg", "damping_ratio", "amplitude_deg", "frequency_hz")
#: the name of the repeats' (type A) contribution
REPEATS = "repeats"


def _relative_inputs(row: pd.Series, u: RigUncertainty) -> dict[str, dict[str, float]]:
    """quantity -> input -> relative standard uncertainty of one condition (module docstring)."""
    out: dict[str, dict[str, float]] = {q: {} for q in BUDGET_QUANTITIES}
    j = float(row.get("inertia_kgm2", math.nan))
    entry = None
    if math.isfinite(j):  # a condition without an inertia has no J term
        entry = u.inertia(j)
    if entry is not None:
        out["stiffness_nm_per_deg"]["inertia_kgm2"] = entry.standard / j
    fs = float(row.get("sample_rate_hz", math.nan))
    if u.sample_rate_hz is not None and math.isfinite(fs) and fs > 0:
        out["frequency_hz"]["sample_rate_hz"] = u.sample_rate_hz.standard / fs
        out["stiffness_nm_per_deg"]["sample_rate_hz"] = 2 * u.sample_rate_hz.standard / fs
    r = float(row.get("sensor_radius_m", math.nan))
    if u.laser_radius_m is not None and math.isfinite(r) and r > 0:
        out["amplitude_deg"]["laser_radius_m"] = u.laser_radius_m.standard / r
    if u.laser_calibration_rel is not None:
        out["amplitude_deg"]["laser_calibration_rel"] = u.laser_calibration_rel.standard
    return out


@expects(results=pd.DataFrame)
def condition_budgets(results: pd.DataFrame, uncertainty: RigUncertainty | None = None) -> pd.DataFrame:
    """The budget of every condition's mean.

    Parameters
    ----------
    results : pandas.DataFrame
        One row per test (``extract`` rows or a campaign's ``results.parquet``), with the
        quantities of :data:`BUDGET_QUANTITIES` (and their ``*_std``); the conditions are the
        distinct values of the :data:`CONDITION_COLUMNS` present.
    uncertainty : RigUncertainty, optional
        The rig's input uncertainties; None: the repeats' share alone.

    Returns
    -------
    pandas.DataFrame
        One row per condition and quantity: the condition's columns, ``quantity``, ``n_tests``,
        ``value`` (the mean, the quantity's unit), ``u_repeats`` and ``u_<input>`` (standard, the
        quantity's unit; absent inputs: not given), ``u_c``, ``U95`` (k = 2), ``U95_pct``,
        ``dominant`` and ``dominant_share_pct`` (its u_i²/u_c²).
    """
    keys = [c for c in CONDITION_COLUMNS if c in results.columns]
    if not keys:
        raise DroptowerError(f"the results name no condition (none of {', '.join(CONDITION_COLUMNS)})",
                             where="results")
    u = uncertainty or RigUncertainty()
    rows = []
    for values, group in results.groupby(keys, dropna=False, sort=True):
        values = values if isinstance(values, tuple) else (values,)
        inputs = _relative_inputs(group.iloc[0], u)
        for q in BUDGET_QUANTITIES:
            if q not in group.columns:
                continue
            x = pd.to_numeric(group[q], errors="coerce").to_numpy(float)
            x = x[np.isfinite(x)]
            if x.size == 0:
                continue
            mean = float(np.mean(x))
            if x.size >= 2:
                u_rep = float(np.std(x, ddof=1) / math.sqrt(x.size))
            else:
                std = pd.to_numeric(group.get(f"{q}_std", pd.Series([math.nan])), errors="coerce").to_numpy(float)
                u_rep = float(std[0]) if std.size else math.nan
            parts = {REPEATS: u_rep, **{name: abs(mean) * rel for name, rel in inputs[q].items()}}
            finite = {k: v for k, v in parts.items() if math.isfinite(v)}
            u_c = math.sqrt(sum(v * v for v in finite.values())) if finite else math.nan
            dominant = max(finite, key=finite.get) if finite and u_c > 0 else ""
            row = dict(zip(keys, values))
            row.update(quantity=q, n_tests=int(x.size), value=mean, u_repeats=u_rep,
                       **{f"u_{k}": v for k, v in parts.items() if k != REPEATS})
            row.update(u_c=u_c, U95=COVERAGE_FACTOR * u_c, U95_pct=100 * COVERAGE_FACTOR * u_c / abs(mean) if mean else math.nan,
                       dominant=dominant, dominant_share_pct=100 * finite[dominant] ** 2 / u_c ** 2 if dominant else math.nan)
            rows.append(row)
    return pd.DataFrame(rows)
