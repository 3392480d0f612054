"""Validate a characteristic map against servo-hydraulic points (Rapp et al. 2022, Fig. 14, docs/theory.md#servo, #damping-measures).

The map (Rapp et al. 2022, eq. 19, eq. 20) predicts stiffness and damping ratio at every servo point;
the deviations, ``100 (map - servo) / servo`` in percent, are summarised per region:
``inside`` the convex hull of the drop tests' (amplitude, frequency) points, where the map
interpolates (:meth:`MapFit.in_range`); ``rectangle``, inside the rectangle of the tests'
extremes, the paper's statement of its range ("~20-60 Hz, ~0.15-3.2 deg": its corners hold no
test, since larger drops give larger amplitudes at lower frequencies); ``outside`` the hull;
``all`` (the paper: within 6 % stiffness and about 7 % damping, errors growing outside).

Damping like with like (docs/theory.md#damping-measures): the map's damping is the drop tower's d_ratio, compared
with the servo's drop-tower-equivalent d_ratio; the loss factor eta and the decay ratio
r = delta/omega of the linear coupling with the map's d_ratio are compared with the servo's
alongside (d grows like exp(4 pi r), so its deviations are about twice eta's), and the
relative damping psi (DIN 740-2, W_D / W_el) is reported.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from droptower.compare.servo_points import ServoPoints
from droptower import sdof
from droptower.maps import MapFit
from droptower.deprecation import moved_names
from droptower.errors import expects

if TYPE_CHECKING:
    from droptower.compare.model_map import ModelMap

COLUMNS = ("sweep", "amplitude_deg", "frequency_hz", "in_range", "in_rectangle", "servo_stiffness_nm_per_deg",
           "map_stiffness_nm_per_deg", "stiffness_deviation_pct", "servo_damping_ratio", "map_damping_ratio",
           "damping_deviation_pct", "servo_lehr_damping", "map_lehr_damping", "servo_loss_factor", "map_loss_factor", "loss_factor_deviation_pct",
           "servo_decay_ratio", "map_decay_ratio", "decay_ratio_deviation_pct", "servo_relative_damping_psi",
           "map_relative_damping_psi", "servo_dynamic_stiffness_nm_per_deg")
REGIONS = ("inside", "rectangle", "outside", "all")


@dataclass(frozen=True)
class ServoComparison:
    """What :func:`compare_with_servo` returns (``Validation`` in release 0.1: deprecated): the
    comparison table (one row per sweep point, :data:`COLUMNS`) and its summary: per
    region (``inside``, ``outside``, ``all`` the map's measured range) the number of distinct
    points and the RMS and maximum absolute deviations (percent) of stiffness and damping."""

    table: pd.DataFrame
    summary: dict[str, Any]


def deviation_stats(stiffness_pct: np.ndarray, damping_pct: np.ndarray, loss_factor_pct: np.ndarray | None = None,
                    decay_ratio_pct: np.ndarray | None = None) -> dict[str, Any]:
    """n_points and RMS / max |deviation| (percent) of stiffness and damping ratio (and of the
    loss factor and decay ratio r where given); NaN for no points."""
    def rms(x):
        return float(np.sqrt(np.mean(np.square(x)))) if x.size else math.nan

    def peak(x):
        return float(np.max(np.abs(x))) if x.size else math.nan

    out = {"n_points": int(stiffness_pct.size),
           "stiffness_rms_deviation_pct": rms(stiffness_pct), "stiffness_max_deviation_pct": peak(stiffness_pct),
           "damping_rms_deviation_pct": rms(damping_pct), "damping_max_deviation_pct": peak(damping_pct)}
    for name, values in (("loss_factor", loss_factor_pct), ("decay_ratio", decay_ratio_pct)):
        if values is not None:
            out[f"{name}_rms_deviation_pct"] = rms(values)
            out[f"{name}_max_deviation_pct"] = peak(values)
    return out


def map_damping_measures(damping_ratio: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(eta, psi) of the linear Kelvin-Voigt coupling whose drop-tower damping ratio is given:
    r = delta/omega from eq. 16, eta = 2r / (1 + r^2), psi = 2 pi eta / sqrt(1 + eta^2) (DIN 740-2,
    W_el = T_hat phi_hat / 2, as the servo bench evaluates it; docs/theory.md#damping-measures)."""
    r = sdof.decay_ratio(damping_ratio)
    return sdof.loss_factor(r, 1.0), sdof.relative_damping(r, 1.0)


@expects(fit=("droptower.maps.mapfit.MapFit", "droptower.compare.model_map.ModelMap"), points="droptower.compare.servo_points.ServoPoints")
def compare_with_servo(fit: MapFit | ModelMap, points: ServoPoints) -> ServoComparison:
    """Predict every servo point from the map (the paper's :class:`MapFit` or a model-based
    :class:`~droptower.compare.model_map.ModelMap`) and compare (module docstring)."""
    servo = points.table
    a, f = servo["amplitude_deg"].to_numpy(float), servo["frequency_hz"].to_numpy(float)
    c_map = fit.stiffness_nm_per_deg(a, f)
    d_map = fit.damping_ratio(a, f)
    eta_map, psi_map = map_damping_measures(d_map)
    r_map = sdof.decay_ratio(d_map)
    r_servo = sdof.decay_ratio(servo["servo_damping_ratio"].to_numpy(float))
    table = servo.assign(
        in_range=fit.in_range(a, f), in_rectangle=fit.in_rectangle(a, f),
        map_stiffness_nm_per_deg=c_map,
        stiffness_deviation_pct=100 * (c_map / servo["servo_stiffness_nm_per_deg"] - 1),
        map_damping_ratio=d_map,
        damping_deviation_pct=100 * (d_map / servo["servo_damping_ratio"] - 1),
        map_loss_factor=eta_map, loss_factor_deviation_pct=100 * (eta_map / servo["servo_loss_factor"] - 1),
        servo_decay_ratio=r_servo, map_decay_ratio=r_map, decay_ratio_deviation_pct=100 * (r_map / r_servo - 1),
        map_relative_damping_psi=psi_map,
        servo_lehr_damping=sdof.lehr_damping(r_servo, 1.0), map_lehr_damping=sdof.lehr_damping(r_map, 1.0),
    )[list(COLUMNS)]
    distinct = table.drop_duplicates(["amplitude_deg", "frequency_hz"])  # a point on two sweeps counts once
    summary: dict[str, Any] = {}
    for region, rows in region_rows(distinct).items():
        summary[region] = deviation_stats(*(rows[f"{q}_deviation_pct"].to_numpy(float)
                                            for q in ("stiffness", "damping", "loss_factor", "decay_ratio")))
    r = fit.range
    summary.update(servo_source=points.source, stiffness_definition=points.stiffness_definition,
                   damping_definition=points.damping_definition,
                   map_range={"amplitude_deg_min": r.amplitude_deg_min, "amplitude_deg_max": r.amplitude_deg_max,
                              "frequency_hz_min": r.frequency_hz_min, "frequency_hz_max": r.frequency_hz_max,
                              "hull_amplitude_deg_frequency_hz": [list(v) for v in r.hull]},
                   map_source=fit.source)
    return ServoComparison(table, summary)


def region_rows(table: pd.DataFrame) -> dict[str, pd.DataFrame]:
    """The rows of a table with ``in_range`` (hull) and ``in_rectangle`` columns, per region of
    :data:`REGIONS`."""
    return {"inside": table[table["in_range"]], "rectangle": table[table["in_rectangle"]],
            "outside": table[~table["in_range"]], "all": table}


@expects(validation="droptower.compare.map_vs_servo.ServoComparison")
def format_summary(validation: ServoComparison) -> str:
    """The summary as text: definitions, then RMS / max deviations per region."""
    s = validation.summary
    r = s["map_range"]
    lines = [f"servo points: {s['servo_source']}",
             f"stiffness: {s['stiffness_definition']}",
             f"damping: {s['damping_definition']}",
             f"drop tower's measured range: the hull of the tested points ({len(r['hull_amplitude_deg_frequency_hz'])} "
             f"vertices) within {r['amplitude_deg_min']:.3g}-{r['amplitude_deg_max']:.3g} deg, "
             f"{r['frequency_hz_min']:.3g}-{r['frequency_hz_max']:.3g} Hz (the rectangle)",
             f"{'':<24}{'points':>7}{'stiffness rms':>15}{'max':>8}{'d rms':>8}{'max':>8}{'eta rms':>9}"
             f"{'r rms':>8}   (deviation, %)"]
    labels = {"inside": "inside the hull", "rectangle": "inside the rectangle", "outside": "outside the hull",
              "all": "all points"}
    for region in REGIONS:
        x = s[region]
        lines.append(f"{labels[region]:<24}{x['n_points']:>7}{_pct(x['stiffness_rms_deviation_pct'], 15)}"
                     f"{_pct(x['stiffness_max_deviation_pct'], 8)}{_pct(x['damping_rms_deviation_pct'], 8)}"
                     f"{_pct(x['damping_max_deviation_pct'], 8)}{_pct(x.get('loss_factor_rms_deviation_pct', math.nan), 9)}"
                     f"{_pct(x.get('decay_ratio_rms_deviation_pct', math.nan), 8)}")
    return "\n".join(lines)


#: the quantities a route table reports per region (RMS deviation from the servo points, %)
ROUTE_QUANTITIES = ("stiffness", "loss_factor", "damping")


def validate_routes(routes: dict[str, Any], points: ServoPoints, hull: Any | None = None) -> dict[str, ServoComparison]:
    """Each named route (a map: the paper's :class:`MapFit` or a model-based
    :class:`~droptower.compare.model_map.ModelMap`) against the same servo points, by
    :func:`compare_with_servo`. ``hull``: the map whose measured range sets every route's regions
    (default: each route's own), so that the routes are compared on the same points."""
    out = {}
    for name, route in routes.items():
        v = compare_with_servo(route, points)
        if hull is not None and hull is not route:
            table = v.table.assign(**{"in_range": hull.in_range(v.table["amplitude_deg"], v.table["frequency_hz"]),
                                      "in_rectangle": hull.in_rectangle(v.table["amplitude_deg"], v.table["frequency_hz"])})
            distinct = table.drop_duplicates(["amplitude_deg", "frequency_hz"])
            summary = dict(v.summary)
            for region, rows in region_rows(distinct).items():
                summary[region] = deviation_stats(*(rows[f"{q}_deviation_pct"].to_numpy(float)
                                                    for q in ("stiffness", "damping", "loss_factor", "decay_ratio")))
            v = ServoComparison(table, summary)
        out[name] = v
    return out


def route_table(validations: dict[str, ServoComparison]) -> pd.DataFrame:
    """One row per route and region (inside / outside the hull, all): points and RMS / max
    deviations (%) of stiffness (map c or model K' vs the servo's K'), loss factor and d."""
    rows = []
    for name, v in validations.items():
        for region in ("inside", "outside", "all"):
            s = v.summary[region]
            rows.append({"route": name, "region": region, "n_points": s["n_points"],
                         **{f"{q}_{k}_deviation_pct": s.get(f"{q}_{k}_deviation_pct", math.nan)
                            for q in ROUTE_QUANTITIES for k in ("rms", "max")}})
    return pd.DataFrame(rows)


def format_routes(validations: dict[str, ServoComparison]) -> str:
    """The routes side by side as text: RMS deviation from the servo points per region."""
    table = route_table(validations)
    width = max(24, *(len(n) + 2 for n in validations))
    lines = [f"{'route':<{width}}{'region':<9}{'points':>7}{'K rms':>8}{'eta rms':>9}{'d rms':>8}   (deviation from "
             "the servo bench, %)"]
    for r in table.itertuples():
        lines.append(f"{r.route:<{width}}{r.region:<9}{r.n_points:>7}{_pct(r.stiffness_rms_deviation_pct, 8)}"
                     f"{_pct(r.loss_factor_rms_deviation_pct, 9)}{_pct(r.damping_rms_deviation_pct, 8)}")
    return "\n".join(lines)


def _pct(value: float, width: int) -> str:
    """A deviation (%) right-aligned in ``width`` characters: two decimals, or powers of ten where
    those would not fit (a map extrapolated far out of its range: the columns stay columns)."""
    text = f"{value:.2f}"
    if len(text) >= width:
        text = f"{value:.1e}"
    return f"{text:>{width}}"


def validate_map(fit: MapFit | ModelMap, points: ServoPoints) -> ServoComparison:
    """Deprecated (removed in the next release): :func:`compare_with_servo`, whose result
    :class:`ServoComparison` its name pairs with."""
    from droptower.deprecation import warn_deprecated

    warn_deprecated("validate_map()", "compare_with_servo()")
    return compare_with_servo(fit, points)


__getattr__ = moved_names(__name__, {"Validation": "ServoComparison"}, globals())
