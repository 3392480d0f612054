"""Reports of a drop-test identification: JSON, text, and the fitted model's prediction on the
virtual servo bench beside the drop tower's map of the same logs, as a table and a figure.

Messages name Python parameters in backticks (``verbose``); the command line says its flags.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from droptower.errors import DroptowerError
from droptower.identify.drop_campaign import DropCampaign
from droptower.identify.result import DROPS, Identification, register_format, report_text, result_skeleton

#: The servo grid of the prediction: amplitudes x frequencies, log-spaced over the tested range.


def drop_result_dict(result: Identification) -> dict[str, Any]:
    """A drop-test identification, JSON-ready, with the keys of
    :data:`~droptower.identify.result.RESULT_KEYS` (also what the ``identify`` command prints as
    JSON for drop tests); its errors carry ``nrmse``, the angle's, as the servo records' do the torque's."""
    from droptower.jsonsafe import json_safe

    doc = result_skeleton(result)
    doc.update(fit_error={"nrmse": result.fit_error["angle_nrmse"], **result.fit_error},
               holdout_error={"nrmse": result.holdout_error["angle_nrmse"], **result.holdout_error}
               if result.holdout_error else None)
    return json_safe(doc)


def drop_report_text(result: Identification, verbose: bool = False) -> str:
    """The text report of a drop-test identification (the sections of
    :data:`~droptower.identify.result.SUMMARY_SECTIONS`); ``verbose``: a line per test."""
    data = (f"drop tests ({len(result.tests_used)} fitted, {len(result.tests_held_out)} held out, "
            f"{len(result.tests_excluded)} excluded)")
    errors = []
    for label, err in (("fit", result.fit_error), ("holdout", result.holdout_error)):
        if err:
            errors.append(f"{label + ':':<8} angle nRMSE {100 * err['angle_nrmse']:.3f} % (max {100 * err['angle_nrmse_max']:.3f} %)"
                          + (f", torque nRMSE {100 * err['torque_nrmse']:.3f} %" if "torque_nrmse" in err else "")
                          + f" over {err['tests']} test(s)")
    if not result.holdout_error:
        errors.append("holdout: none (no held-out tests)")
    sources = sorted({r["rate_source"] for r in result.fit_error["per_test"]})
    details = [f"initial rate from: {', '.join(sources)} (impact_force: L * impulse / J; angle_slope: the angle's "
               "slope after the onset)"]
    per_test = result.fit_error["per_test"] + (result.holdout_error["per_test"] if result.holdout_error else [])
    if not verbose:
        worst = max(per_test, key=lambda r: r["angle_nrmse"])
        details.append(f"per test: {len(per_test)} test(s), worst angle nRMSE {100 * worst['angle_nrmse']:.3f} % "
                       f"({worst['file']}); `verbose` lists every test")
    else:
        details.append("per test (angle nRMSE %):")
        for r in per_test:
            held = " (held out)" if r["file"] in result.tests_held_out else ""
            details.append(f"  {r['file']}: J {r['inertia_kgm2']:.4g} kg*m^2, {r['amplitude_deg']:.3g} deg, "
                           f"{r['frequency_hz']:.3g} Hz: {100 * r['angle_nrmse']:.3f}{held}")
        for e in result.tests_excluded:
            details.append(f"  excluded {e['file']}: {e['reason']}")
    return report_text(result, data, errors, details)


def servo_prediction(result: Identification, campaign: DropCampaign) -> tuple[pd.DataFrame, str]:
    """The fitted model on a servo grid over the tested amplitude and frequency range (K', loss
    factor, the drop-tower-equivalent damping ratio), next to the drop tower's map (Rapp et al. 2022,
    eq. 19-20 fitted to the first-cycle evaluations of the same logs) at the same points.
    Returns the table and a note on the map."""
    from droptower.extract.files import Settings, extract_file, result_row
    from droptower.identify.dropfit import servo_grid, tested_grid
    from droptower.maps.fitting import fit_map

    decays, paths, settings = campaign.decays, campaign.paths, campaign.read
    grid = servo_grid(result.coupling, *tested_grid(decays))
    table = pd.DataFrame({
        "amplitude_deg": grid["amplitude_deg"], "frequency_hz": grid["frequency_hz"],
        "model_storage_stiffness_nm_per_deg": grid["storage_stiffness_nm_per_deg"],
        "model_loss_factor": grid["loss_factor"],
        "model_drop_tower_equivalent_damping_ratio": grid["drop_tower_equivalent_damping_ratio"]})
    used = {d.name for d in decays}
    rows = []
    for p in paths:
        if Path(p).name in used:
            try:
                rows.append(result_row(p, *extract_file(p, Settings(roles=settings.roles, defaults=settings.defaults))))
            except DroptowerError:
                continue
    try:
        fitted = fit_map(pd.DataFrame(rows), source="the drop tests")
    except DroptowerError as exc:
        return table, f"no drop-tower map: {exc.problem}"
    a, f = table["amplitude_deg"].to_numpy(), table["frequency_hz"].to_numpy()
    table["map_stiffness_nm_per_deg"] = fitted.stiffness_nm_per_deg(a, f)
    table["map_damping_ratio"] = fitted.damping_ratio(a, f)
    return table, f"drop-tower map (Rapp et al. 2022, eq. 19-20) from {len(rows)} first-cycle evaluations"


#: two curves closer than this share of their axis's span everywhere look like one line (about
#: 2 px on a 400 px axis): they are drawn once, with one legend entry naming both
COINCIDE = 0.005


def _frequencies(freqs: list[float]) -> str:
    text = [f"{f:.3g}" for f in freqs]
    return text[0] if len(text) == 1 else f"{', '.join(text[:-1])} and {text[-1]}"


def distinct_curves(curves: list[tuple[float, np.ndarray, np.ndarray]], span: float) -> list[tuple[list[float], np.ndarray, np.ndarray]]:
    """Curves ``(frequency, x, y)`` grouped so that curves within :data:`COINCIDE` x ``span`` of a
    group's first one join it: one drawn line and one legend entry per group."""
    groups: list[tuple[list[float], np.ndarray, np.ndarray]] = []
    for f, x, y in curves:
        for freqs, gx, gy in groups:
            if len(gx) == len(x) and np.allclose(gx, x) and np.max(np.abs(gy - y)) <= COINCIDE * span:
                freqs.append(f)
                break
        else:
            groups.append(([f], x, y))
    return groups


def servo_prediction_figure(table: pd.DataFrame) -> Any:
    """Stiffness and damping ratio over amplitude: the fitted model on the servo bench (solid)
    and the drop tower's map (dashed), a colour per frequency; curves that coincide are drawn
    once and named together in the legend."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(12, 5), layout="constrained")
    ax_k, ax_d = fig.subplots(1, 2)
    colour = {f: f"C{i}" for i, f in enumerate(sorted(table["frequency_hz"].unique()))}
    panels = ((ax_k, "model_storage_stiffness_nm_per_deg", "map_stiffness_nm_per_deg"),
              (ax_d, "model_drop_tower_equivalent_damping_ratio", "map_damping_ratio"))
    for ax, model_col, map_col in panels:
        for who, col, style in (("model", model_col, "-"), ("map", map_col, "--")):
            if col not in table:
                continue
            curves = [(f, part["amplitude_deg"].to_numpy(float), part[col].to_numpy(float))
                      for f, part in table.sort_values("amplitude_deg").groupby("frequency_hz")]
            values = table[[c for c in (model_col, map_col) if c in table]].to_numpy(float)
            span = float(np.nanmax(values) - np.nanmin(values)) or 1.0
            for freqs, x, y in distinct_curves(curves, span):
                ax.plot(x, y, style, color=colour[freqs[0]], label=f"{who}, {_frequencies(freqs)} Hz")
        ax.set_xlabel("amplitude (deg)")
        ax.legend(fontsize=7, ncol=2, loc="upper center", bbox_to_anchor=(0.5, -0.14))  # below: off the curves
    ax_k.set_ylabel("stiffness (N*m/deg)")
    ax_k.set_title("stiffness: model K', map c", fontsize=10)
    ax_d.set_ylabel("d = E_diss/E_el (Rapp et al. 2022)")
    ax_d.set_title("drop-tower damping ratio (model: the d of its loss factor)", fontsize=10)
    fig.suptitle("fitted model on the servo bench (solid) vs the drop tower's map (dashed)")
    return fig


def plot_servo_prediction(table: pd.DataFrame, out_dir: str | Path) -> Path:
    """:func:`servo_prediction_figure` as ``identify_drop_servo_prediction.png`` in ``out_dir``."""
    from droptower.io.droptower_log import save_figure

    return save_figure(servo_prediction_figure(table), Path(out_dir) / "identify_drop_servo_prediction.png", 110)


register_format(DROPS, drop_result_dict, drop_report_text)
