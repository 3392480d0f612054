"""Reports of identifications: dictionaries (JSON), text, comparison tables and plots.

Every field carries its unit in its name, for the records' units (``k1_nm_per_rad`` for
torsional records, ``k1_n_per_m`` for translational ones, see :mod:`droptower.io.fields`);
RMSE values are given as the fraction ``nrmse`` and as ``nrmse_percent`` of the largest
measured |torque| or |force| (the zero-dimensional model paper's measure).
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from droptower.errors import make_folder
from droptower.identify.data import Segment
from droptower.identify.result import Identification, metrics, servo_residual
from droptower.identify.result import SERVO, register_format, report_text, result_skeleton
from droptower.io.droptower_log import save_figure
from droptower.io.fields import field_name, translate_fields
from droptower.jsonsafe import json_safe


def result_dict(ident: Identification) -> dict[str, Any]:
    """Everything an identification from servo records reports, JSON-ready, with the keys of
    :data:`~droptower.identify.result.RESULT_KEYS`, fields named for the records' units
    (parameter names given as values, in ``at_bounds`` and a stage's ``free``, too)."""
    units = ident.coupling.units

    def named(names: list[str]) -> list[str]:
        return [field_name(n, units) for n in names]

    doc = result_skeleton(ident)
    doc.update(
        at_bounds=named(ident.at_bounds),
        non_identifiable=ident.non_identifiable or (ident.stages[-1].non_identifiable if ident.stages else []),
        fit_error=ident.fit_error.to_dict(),
        holdout_error=ident.holdout_error.to_dict() if ident.holdout_error else None,
        stages=[s.to_dict() | {"free": named(s.to_dict()["free"])} for s in ident.stages])
    return translate_fields(json_safe(doc), units) | {"units": units}


def result_text(ident: Identification) -> str:
    """The text report of an identification from servo records (the sections of
    :data:`~droptower.identify.result.SUMMARY_SECTIONS`; names for the records' units)."""
    units = ident.coupling.units
    load, unit = ("force", "N") if units == "translational" else ("torque", "N*m")
    data = "servo records" + (" (translational: displacement in m, force in N)" if units == "translational" else "")
    errors = []
    for label, m in (("fit", ident.fit_error), ("holdout", ident.holdout_error)):
        if m:
            errors.append(f"{label + ':':<8} nRMSE {100 * m.nrmse:.3f} % of max |{load}| {m.max_torque_nm:.4g} {unit} "
                          f"(RMSE {m.rmse_nm:.4g} {unit}), residual lag-1 correlation {m.residual_lag1:.3f}")
    if not ident.holdout_error:
        errors.append("holdout: none (no hold-out records)")
    details = [f"stage {s.stage}: nRMSE {100 * s.metrics.nrmse:.3f} %, {s.nfev} steps, {s.evaluations} evaluations, "
               f"{s.time_s:.2f} s, {'converged' if s.converged else 'not converged: ' + s.message}" for s in ident.stages]
    if ident.coupling_note:
        details.append(f"coupling: {ident.coupling_note}")
    if "start" in ident.extra:
        st = ident.extra["start"]
        details.append(f"start: the {st['family']} fit (nRMSE {100 * st['nrmse']:.3f} %"
                       + (", its global search included" if st["global_search"] else "")
                       + (f", {st['evaluations']} evaluations, counted above" if "evaluations" in st else "") + ")")
    if "staged_fit" in ident.extra:
        details.append(f"staged fit before the global search: nRMSE {100 * ident.extra['staged_fit']['nrmse']:.3f} %")
    extra = translate_fields(ident.extra, units)
    for key in ("analytic", "loading_curve", "p_walk", "amplitude_functions", "frequency_functions"):
        if key in extra:
            details.append(f"{key.replace('_', ' ')}: {_brief(extra[key])}")
    return report_text(ident, data, errors, details, name_of=lambda n: field_name(n, units))


register_format(SERVO, result_dict, result_text)


def _brief(value: Any) -> str:
    if isinstance(value, dict):
        return "; ".join(f"{k} {_brief(v)}" for k, v in value.items())
    if isinstance(value, (float, np.floating)):
        return f"{float(value):.4g}"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_brief(v) for v in value) + "]"
    return str(value)


# ---------------------------------------------------------------------------- comparison
def ranking_table(results: dict[str, Identification], segments: list[Segment]) -> pd.DataFrame:
    """One row per family, best first by :data:`~droptower.identify.criterion.RULE`, every
    family scored on the same compared samples of ``segments`` (its fitting data) against the
    data's own noise floor; ``delta_bic`` is the distance to the best (above ~10: strong
    evidence against the family)."""
    from droptower.identify.criterion import bic
    from droptower.identify.noise import servo_noise

    noise = servo_noise(segments)
    rss = {kind: float(np.sum(servo_residual(segments, r.predict(segments)) ** 2)) for kind, r in results.items()}
    # records too short to smooth: the best family's RMS error stands in for the noise (the
    # same constant for every family: the order is unchanged)
    sigma = noise.sigma if math.isfinite(noise.sigma) else math.sqrt(min(rss.values()) / max(noise.n_samples, 1))
    rows = []
    for kind, r in results.items():
        rows.append({"family": kind, "n_parameters": r.n_parameters, "fit_nrmse_percent": 100 * r.fit_error.nrmse,
                     "holdout_nrmse_percent": 100 * r.holdout_error.nrmse if r.holdout_error else np.nan,
                     "bic": bic(rss[kind], noise.n_samples, noise.n_eff, sigma, r.n_parameters),
                     "verdict": r.verdict.verdict if r.verdict else None,
                     "wall_s": r.wall_s, "evaluations": r.evaluations, "converged": r.converged})
    return ranked(pd.DataFrame(rows), {"noise_floor_nm": sigma, "n_eff": noise.n_eff})


def drop_ranking_table(results: dict[str, Any]) -> pd.DataFrame:
    """Families fitted to one drop-test campaign (:class:`~droptower.identify.result.Identification`
    from drop tests each, the same fitting tests), ranked like :func:`ranking_table`: the likelihood term on the
    angle error over the same compared samples, the noise model the logs' pre-trigger noise
    with the re-simulation's accuracy in quadrature (the verdict's allowance), the sensor noise
    white (n_eff = n)."""
    from droptower.identify.criterion import bic

    first = next(iter(results.values()))
    sigma, n = first.verdict.allowance, first.angle_samples
    rows = []
    for kind, r in results.items():
        if r.angle_samples != n:
            raise ValueError("drop-test fits ranked together must share their fitting tests")
        rows.append({"family": kind, "n_parameters": r.n_parameters,
                     "fit_angle_nrmse_percent": 100 * r.fit_error["angle_nrmse"],
                     "holdout_angle_nrmse_percent": 100 * r.holdout_error["angle_nrmse"] if r.holdout_error else np.nan,
                     "bic": bic(r.angle_rss_rad2, n, float(n), sigma, r.n_parameters),
                     "verdict": r.verdict.verdict, "wall_s": r.wall_s, "evaluations": r.evaluations,
                     "converged": r.converged})
    return ranked(pd.DataFrame(rows), {"noise_allowance_rad": sigma, "n_eff": float(n)})


def ranked(table: pd.DataFrame, common: dict[str, float]) -> pd.DataFrame:
    """``table`` (columns family, n_parameters, bic, converged) best first by the criterion's
    rule, with ``delta_bic`` and the ``common`` columns (the noise model, the effective sample size)."""
    from droptower.identify.criterion import order

    if table.empty:
        return table
    names = [m for ok in (True, False) for m in
             order(list(zip(*(table.loc[table["converged"] == ok, c] for c in ("family", "n_parameters", "bic")))))]
    table = table.set_index("family").loc[names].reset_index()
    best = table["bic"][table["converged"]].min() if table["converged"].any() else table["bic"].min()
    table.insert(table.columns.get_loc("bic") + 1, "delta_bic", table["bic"] - best)
    for key, value in common.items():
        table[key] = value
    table.index = table.index + 1
    return table


def record_table(results: dict[str, Identification], segments: list[Segment]) -> pd.DataFrame:
    """The zero-dimensional model paper, Fig. 8 as a table: per record and model, the RMSE as percent of the largest
    |torque| of all records (8b) and relative to the largest RMSE of that record over the
    models (8a)."""
    peak = max(float(np.nanmax(np.abs(s.torque_nm))) for s in segments)
    rows = []
    for kind, r in results.items():
        predictions = r.predict(segments)
        for seg, pred in zip(segments, predictions):
            m = metrics([seg], [pred])
            rows.append({"record": seg.name, "family": kind, "rmse_nm": m.rmse_nm, "nrmse_percent": 100 * m.rmse_nm / peak})
    table = pd.DataFrame(rows)
    if not table.empty:
        table["rmse_over_max_rmse"] = table["rmse_nm"] / table.groupby("record")["rmse_nm"].transform("max")
    return table.rename(columns=lambda c: field_name(c, segments[0].units))


# ---------------------------------------------------------------------------- plots
def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _axes(units: str) -> tuple[str, str, float]:
    """Plot labels and scale for the records' units: load axis, motion axis, motion factor
    from SI (rad -> deg, m -> mm)."""
    if units == "translational":
        return "force [N]", "displacement [mm]", 1e3
    return "torque [N*m]", "angle [deg]", 180.0 / math.pi


def _safe(name: str) -> str:
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in name)


def plot_identification(ident: Identification, segments: list[Segment], out_dir: str | Path,
                        holdout: list[Segment] | None = None) -> list[Path]:
    """Per record: measured and model torque over time, and the hysteresis loops (torque over
    angle in degrees). Returns the PNG files written."""
    plt = _pyplot()
    out = make_folder(out_dir)
    paths = []
    groups = [("fit", segments)] + ([("holdout", holdout)] if holdout else [])
    load, motion, to_display = _axes(ident.coupling.units)
    for label, segs in groups:
        for seg, pred in zip(segs, ident.predict(segs)):
            fig = plt.figure(figsize=(12, 5.5))
            grid = fig.add_gridspec(2, 2, height_ratios=[3, 1])
            ax_t = fig.add_subplot(grid[0, 0])
            ax_r = fig.add_subplot(grid[1, 0], sharex=ax_t)
            ax_l = fig.add_subplot(grid[:, 1])
            t = np.arange(seg.n) * seg.dt_s
            ok = seg.compared
            ax_t.plot(t[ok], seg.torque_nm[ok], lw=0.8, label="measured")
            ax_t.plot(t[ok], pred[ok], lw=0.8, label=f"model {ident.family}")
            ax_t.set_ylabel(load)
            ax_t.legend()
            # the residual: structure in it is what the model misses
            ax_r.plot(t[ok], seg.torque_nm[ok] - pred[ok], lw=0.6, color="C2", label="measured - model")
            ax_r.axhline(0.0, color="0.3", lw=0.6)
            ax_r.set_xlabel("time [s]")
            ax_r.set_ylabel(f"residual [{load.split('[')[1]}")
            ax_r.legend(fontsize=8)
            deg = to_display * seg.angle_rad
            ax_l.plot(deg[ok], seg.torque_nm[ok], lw=0.6, label="measured")
            ax_l.plot(deg[ok], pred[ok], lw=0.6, label=f"model {ident.family}")
            ax_l.set_xlabel(motion)
            ax_l.set_ylabel(load)
            ax_l.legend()
            m = metrics([seg], [pred])
            fig.suptitle(f"{ident.family} on {seg.name} ({label}): nRMSE {100 * m.nrmse:.2f} %")
            fig.tight_layout()
            path = out / f"identify_{ident.family}_{label}_{_safe(seg.name)}.png"
            save_figure(fig, path, 110)
            plt.close(fig)
            paths.append(path)
    return paths


def plot_comparison(results: dict[str, Identification], records: pd.DataFrame, segment: Segment,
                    out_dir: str | Path) -> list[Path]:
    """The zero-dimensional model paper, Fig. 8 (bars of the per-record RMSE, relative to the largest and in percent of
    the largest torque) and the hysteresis loops of every model overlaid on ``segment``."""
    plt = _pyplot()
    out = make_folder(out_dir)
    paths = []
    fig, axes = plt.subplots(1, 2, figsize=(13, 4.5))
    for ax, col, title in ((axes[0], "rmse_over_max_rmse", "RMSE / max RMSE of the record"),
                           (axes[1], "nrmse_percent", "RMSE (% of max |torque|)")):
        pivot = records.pivot(index="record", columns="family", values=col)
        pivot.plot.bar(ax=ax, rot=30)
        ax.set_title(title)
        ax.set_xlabel("")
    fig.suptitle("models compared per record (the zero-dimensional model paper, Fig. 8)")
    fig.tight_layout()
    paths.append(save_figure(fig, out / "compare_models_rmse.png", 110))
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(7, 6))
    ok = segment.compared
    load, motion, to_display = _axes(segment.units)
    deg = to_display * segment.angle_rad
    ax.plot(deg[ok], segment.torque_nm[ok], color="k", lw=1.2, label="measured")
    for kind, r in results.items():
        ax.plot(deg[ok], r.predict([segment])[0][ok], lw=0.7, label=kind)
    ax.set_xlabel(motion)
    ax.set_ylabel(load)
    ax.set_title(f"hysteresis loops on {segment.name}")
    ax.legend()
    fig.tight_layout()
    paths.append(save_figure(fig, out / "compare_models_loops.png", 110))
    plt.close(fig)
    return paths
