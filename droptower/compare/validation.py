"""Validate a characteristic map against servo-hydraulic points (seed 004 Fig. 14, NOTES §1.6-1.7).

The map (seed 004 eq. 19, eq. 20) predicts stiffness and damping ratio at every servo point;
the deviations, ``100 (map - servo) / servo`` in percent, are summarised separately for points
inside and outside the drop tower's measured amplitude and frequency range
(:meth:`MapFit.in_range`): inside, the map interpolates; outside, it extrapolates (the paper:
within 6 % stiffness and about 7 % damping, errors growing outside ~20-60 Hz, ~0.15-3.2 deg).

Damping like with like (NOTES §1.7): the map's damping is the drop tower's d_ratio, compared
with the servo's drop-tower-equivalent d_ratio; the loss factor eta and the relative damping
psi (DIN 740-2, W_D / W_el) of both are reported alongside, the map's from the linear coupling
with its d_ratio.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from droptower.compare.servo_points import ServoPoints
from droptower import sdof
from droptower.maps import MapFit

COLUMNS = ("sweep", "amplitude_deg", "frequency_hz", "in_range", "servo_stiffness_nm_per_deg",
           "map_stiffness_nm_per_deg", "stiffness_deviation_pct", "servo_damping_ratio", "map_damping_ratio",
           "damping_deviation_pct", "servo_loss_factor", "map_loss_factor", "servo_relative_damping_psi",
           "map_relative_damping_psi", "servo_dynamic_stiffness_nm_per_deg")
REGIONS = ("inside", "outside", "all")


@dataclass(frozen=True)
class Validation:
    """The comparison table (one row per sweep point, :data:`COLUMNS`) and its summary: per
    region (``inside``, ``outside``, ``all`` the map's measured range) the number of distinct
    points and the RMS and maximum absolute deviations (percent) of stiffness and damping."""

    table: pd.DataFrame
    summary: dict[str, Any]


def deviation_stats(stiffness_pct: np.ndarray, damping_pct: np.ndarray) -> dict[str, Any]:
    """n_points and RMS / max |deviation| (percent) of stiffness and damping; NaN for no points."""
    def rms(x):
        return float(np.sqrt(np.mean(np.square(x)))) if x.size else math.nan

    def peak(x):
        return float(np.max(np.abs(x))) if x.size else math.nan

    return {"n_points": int(stiffness_pct.size),
            "stiffness_rms_deviation_pct": rms(stiffness_pct), "stiffness_max_deviation_pct": peak(stiffness_pct),
            "damping_rms_deviation_pct": rms(damping_pct), "damping_max_deviation_pct": peak(damping_pct)}


def map_damping_measures(damping_ratio: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(eta, psi) of the linear Kelvin-Voigt coupling whose drop-tower damping ratio is given:
    r = delta/omega from eq. 16, eta = 2r / (1 + r^2), psi = 2 pi eta / sqrt(1 + eta^2) (DIN 740-2,
    W_el = T_hat phi_hat / 2, as the servo bench evaluates it; NOTES §1.7)."""
    r = sdof.decay_ratio(damping_ratio)
    return sdof.loss_factor(r, 1.0), sdof.relative_damping(r, 1.0)


def validate_map(fit: MapFit, points: ServoPoints) -> Validation:
    """Predict every servo point from the map and compare (module docstring)."""
    servo = points.table
    a, f = servo["amplitude_deg"].to_numpy(float), servo["frequency_hz"].to_numpy(float)
    c_map = fit.stiffness_nm_per_deg(a, f)
    d_map = fit.damping_ratio(a, f)
    eta_map, psi_map = map_damping_measures(d_map)
    table = servo.assign(
        in_range=fit.in_range(a, f),
        map_stiffness_nm_per_deg=c_map,
        stiffness_deviation_pct=100 * (c_map / servo["servo_stiffness_nm_per_deg"] - 1),
        map_damping_ratio=d_map,
        damping_deviation_pct=100 * (d_map / servo["servo_damping_ratio"] - 1),
        map_loss_factor=eta_map, map_relative_damping_psi=psi_map,
    )[list(COLUMNS)]
    distinct = table.drop_duplicates(["amplitude_deg", "frequency_hz"])  # a point on two sweeps counts once
    summary: dict[str, Any] = {}
    for region, rows in (("inside", distinct[distinct["in_range"]]), ("outside", distinct[~distinct["in_range"]]),
                         ("all", distinct)):
        summary[region] = deviation_stats(rows["stiffness_deviation_pct"].to_numpy(float),
                                          rows["damping_deviation_pct"].to_numpy(float))
    r = fit.range
    summary.update(servo_source=points.source, stiffness_definition=points.stiffness_definition,
                   damping_definition=points.damping_definition,
                   map_range={"amplitude_deg_min": r.amplitude_deg_min, "amplitude_deg_max": r.amplitude_deg_max,
                              "frequency_hz_min": r.frequency_hz_min, "frequency_hz_max": r.frequency_hz_max},
                   map_source=fit.source)
    return Validation(table, summary)


def format_summary(validation: Validation) -> str:
    """The summary as text: definitions, then RMS / max deviations inside and outside the range."""
    s = validation.summary
    r = s["map_range"]
    lines = [f"servo points: {s['servo_source']}",
             f"stiffness: {s['stiffness_definition']}",
             f"damping: {s['damping_definition']}",
             f"drop tower's measured range: {r['amplitude_deg_min']:.3g}-{r['amplitude_deg_max']:.3g} deg, "
             f"{r['frequency_hz_min']:.3g}-{r['frequency_hz_max']:.3g} Hz",
             f"{'':<22}{'points':>7}{'stiffness rms':>15}{'max':>9}{'damping rms':>14}{'max':>9}   (deviation, %)"]
    for region, label in (("inside", "inside the range"), ("outside", "outside the range"), ("all", "all points")):
        x = s[region]
        lines.append(f"{label:<22}{x['n_points']:>7}{x['stiffness_rms_deviation_pct']:>15.2f}"
                     f"{x['stiffness_max_deviation_pct']:>9.2f}{x['damping_rms_deviation_pct']:>14.2f}"
                     f"{x['damping_max_deviation_pct']:>9.2f}")
    return "\n".join(lines)
