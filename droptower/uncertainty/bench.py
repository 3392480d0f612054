"""The servo bench's own expanded uncertainty from its record (GUM 4.2 and 4.3): the type A part
from the scatter of the evaluated cycles, the type B part from the stated calibrations of its
torque (force) and angle (displacement) channels.

Per block of an evaluated record (:func:`droptower.servo.records.evaluate_records`): the mean of
n single cycles has u_A = s/√n (GUM 4.2.3; s the cycles' standard deviation, ``*_std``); the
storage stiffness K' = T̂·cos δ/φ̂ carries both calibrations, u_B/K' = √(u_T² + u_φ²) (relative,
first order); the loss factor η = K''/K' and the damping ratio d(η) carry none (the calibrations
cancel in the ratio). u_c² = u_A² + u_B²; U95 = k·u_c with k the Student factor t_0.975(ν_eff) of
the Welch-Satterthwaite degrees of freedom ν_eff = u_c⁴/(u_A⁴/(n − 1)) (GUM G.4; the calibrations'
ν infinite): the scatter of a few cycles is itself uncertain (k = 2.26 for ten cycles and no
calibration, 2 as the calibrations dominate). A block of one cycle has no
scatter: its type A part is not known and its U95 is NaN (validate's verdict: bench uncertainty
not given).
"""
from __future__ import annotations

import math

import numpy as np
import pandas as pd

from droptower.errors import DroptowerError, expects

#: (value column, its cycles' standard deviation column), torsional and translational
STIFFNESS_COLUMNS: tuple[tuple[str, str], ...] = (("storage_stiffness_nm_per_deg", "storage_stiffness_std_nm_per_deg"),
                                                  ("storage_stiffness_n_per_m", "storage_stiffness_std_n_per_m"))


@expects(table=pd.DataFrame)
def bench_u95(table: pd.DataFrame, *, torque_calibration_rel: float | None = None,
              angle_calibration_rel: float | None = None) -> pd.DataFrame:
    """A copy of an evaluated servo table with each block's expanded uncertainty (k = 2).

    Parameters
    ----------
    table : pandas.DataFrame
        ``evaluate_records``' table: ``evaluated_cycles``, the storage stiffness and ``loss_factor``
        with their ``*_std`` over the cycles.
    torque_calibration_rel, angle_calibration_rel : float, optional
        Relative standard uncertainties of the torque (force) and the angle (displacement)
        channels' calibration (0.005: 0.5 %); None: not given (left out, said in
        ``bench_uncertainty_not_given``).

    Returns
    -------
    pandas.DataFrame
        The table with ``<stiffness>_U95``, ``loss_factor_U95`` and, where the table has the
        damping ratio, ``drop_tower_equivalent_damping_ratio_U95`` (the names ``validate``
        reads as the bench's own uncertainty), and ``bench_uncertainty_not_given``.
    """
    from droptower.sdof import drop_tower_equivalent_damping_ratio

    for name, value in (("torque_calibration_rel", torque_calibration_rel), ("angle_calibration_rel", angle_calibration_rel)):
        if value is not None and not (math.isfinite(value) and 0 <= value < 1):
            raise DroptowerError(f"must be a relative standard uncertainty in [0, 1), got {value!r}", where=name)
    if "evaluated_cycles" not in table.columns or "loss_factor" not in table.columns:
        raise DroptowerError("not an evaluated servo table (no evaluated_cycles and loss_factor columns)",
                             where="table")
    out = table.copy()
    n = out["evaluated_cycles"].to_numpy(float)
    calib = math.hypot(torque_calibration_rel or 0.0, angle_calibration_rel or 0.0)
    for value, std in STIFFNESS_COLUMNS:
        if value in out.columns and std in out.columns:
            u_a = out[std].to_numpy(float) / np.sqrt(n)
            u_c = np.hypot(u_a, calib * out[value].to_numpy(float))
            out[f"{value}_U95"] = coverage_factor(u_a, u_c, n) * u_c
    eta = out["loss_factor"].to_numpy(float)
    u_eta = out["loss_factor_std"].to_numpy(float) / np.sqrt(n)
    k_eta = coverage_factor(u_eta, u_eta, n)
    out["loss_factor_U95"] = k_eta * u_eta
    if "drop_tower_equivalent_damping_ratio" in out.columns:  # d(η): its slope at η, central differences
        h = np.maximum(u_eta, 1e-9 * np.abs(eta))
        slope = (drop_tower_equivalent_damping_ratio(eta + h) - drop_tower_equivalent_damping_ratio(eta - h)) / (2 * h)
        out["drop_tower_equivalent_damping_ratio_U95"] = k_eta * np.abs(slope) * u_eta
    missing = [name for name, v in (("torque_calibration_rel", torque_calibration_rel),
                                    ("angle_calibration_rel", angle_calibration_rel)) if v is None]
    out["bench_uncertainty_not_given"] = ";".join(missing)
    return out


def coverage_factor(u_a: np.ndarray, u_c: np.ndarray, n: np.ndarray) -> np.ndarray:
    """k for 95 % of a type A part u_a from n cycles within u_c: Student's t_0.975 at the
    Welch-Satterthwaite ν_eff = u_c⁴ / (u_a⁴/(n − 1)) (GUM G.4.1); 2 where u_a is 0 (ν infinite)."""
    from scipy.stats import t

    u_a, u_c, n = (np.asarray(v, float) for v in (u_a, u_c, n))
    with np.errstate(divide="ignore", invalid="ignore"):
        nu = np.where(u_a > 0, u_c ** 4 / (u_a ** 4 / np.maximum(n - 1.0, 1.0)), np.inf)
    return np.where(np.isfinite(nu), t.ppf(0.975, np.where(np.isfinite(nu), nu, 1.0)), 2.0)
