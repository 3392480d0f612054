"""Reports of identifications: dictionaries (JSON), text, comparison tables and plots.

Every field carries its unit in its name, for the records' units (``k1_nm_per_rad`` for
torsional records, ``k1_n_per_m`` for translational ones, see :mod:`droptower.io.fields`);
RMSE values are given as the fraction ``nrmse`` and as ``nrmse_percent`` of the largest
measured |torque| or |force| (seed 000's measure).
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from droptower.errors import make_folder
from droptower.identify.data import Segment
from droptower.identify.fit import Identification, Metrics, metrics
from droptower.io.fields import field_name, translate_fields
from droptower.io.droptower_log import save_figure


def _clean(value: Any) -> Any:
    """JSON-safe: numpy scalars and arrays to Python, NaN/inf to None."""
    if isinstance(value, dict):
        return {str(k): _clean(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_clean(v) for v in value]
    if isinstance(value, np.ndarray):
        return _clean(value.tolist())
    if isinstance(value, (np.floating, float)):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.bool_):
        return bool(value)
    return value


def result_dict(ident: Identification) -> dict[str, Any]:
    """Everything an identification reports, JSON-ready, fields named for the records' units
    (parameter names given as values, in ``at_bounds`` and a stage's ``free``, too)."""
    units = ident.coupling.units

    def named(names: list[str]) -> list[str]:
        return [field_name(n, units) for n in names]

    return translate_fields(_clean({
        "model": ident.family,
        "converged": ident.converged,
        "n_parameters": ident.n_parameters,
        "parameters": {n: {"value": v, "std_error": ident.std_error.get(n)} for n, v in ident.parameters.items()},
        "derived": ident.derived,
        "at_bounds": named(ident.at_bounds),
        "fit": ident.fit.as_dict(),
        "holdout": ident.holdout.as_dict() if ident.holdout else None,
        "evaluations": ident.evaluations,
        "nfev": ident.nfev,
        "time_s": ident.time_s,
        "stages": [s.summary() | {"free": named(s.summary()["free"])} for s in ident.stages],
        "coupling_note": ident.coupling_note,
        "details": ident.extra,
    }), units) | {"units": units}


def result_text(ident: Identification) -> str:
    """A human-readable report of one identification (names for the records' units)."""
    units = ident.coupling.units
    load, unit = ("force", "N") if units == "translational" else ("torque", "N*m")
    lines = [f"model {ident.family}: {ident.n_parameters} parameters, "
             f"{'converged' if ident.converged else 'NOT CONVERGED'}"
             + (" (translational: displacement in m, force in N)" if units == "translational" else "")]
    values = translate_fields({"parameters": ident.parameters, "std_error": ident.std_error,
                               "derived": ident.derived}, units)
    at_bounds = {field_name(n, units) for n in ident.at_bounds}
    width = max(len(n) for n in list(values["parameters"]) + list(values["derived"]) + ["x"])
    for name, value in values["parameters"].items():
        std = values["std_error"].get(name, float("nan"))
        flag = "  (at bound)" if name in at_bounds else ""
        unc = f" +- {std:.3g}" if math.isfinite(std) else ""
        lines.append(f"  {name:<{width}} = {value:.6g}{unc}{flag}")
    for name, value in values["derived"].items():
        lines.append(f"  {name:<{width}} = {float(value):.6g}  (derived)")
    lines.append(f"fit:     nRMSE {100 * ident.fit.nrmse:.3f} % of max |{load}| {ident.fit.max_torque_nm:.4g} {unit} "
                 f"(RMSE {ident.fit.rmse_nm:.4g} {unit}), residual lag-1 correlation {ident.fit.residual_lag1:.3f}")
    if ident.holdout:
        h = ident.holdout
        lines.append(f"holdout: nRMSE {100 * h.nrmse:.3f} % of max |{load}| {h.max_torque_nm:.4g} {unit} "
                     f"(RMSE {h.rmse_nm:.4g} {unit}), residual lag-1 correlation {h.residual_lag1:.3f}")
    lines.append(f"effort:  {ident.evaluations} model evaluations, {ident.nfev} optimiser steps, "
                 f"{ident.time_s:.2f} s")
    for s in ident.stages:
        lines.append(f"  stage {s.stage}: nRMSE {100 * s.metrics.nrmse:.3f} %, {s.nfev} steps, "
                     f"{s.evaluations} evaluations, {s.time_s:.2f} s, "
                     f"{'converged' if s.converged else 'not converged: ' + s.message}")
    if ident.coupling_note:
        lines.append(f"coupling: {ident.coupling_note}")
    extra = translate_fields(ident.extra, units)
    for key in ("analytic", "loading_curve", "p_walk", "amplitude_functions", "frequency_functions"):
        if key in extra:
            lines.append(f"{key.replace('_', ' ')}: {_brief(extra[key])}")
    return "\n".join(lines)


def _brief(value: Any) -> str:
    if isinstance(value, dict):
        return "; ".join(f"{k} {_brief(v)}" for k, v in value.items())
    if isinstance(value, (float, np.floating)):
        return f"{float(value):.4g}"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_brief(v) for v in value) + "]"
    return str(value)


# ---------------------------------------------------------------------------- comparison
#: How ``compare-models`` ranks (printed with the ranking).
RANKING_RULE = ("ranked by BIC = n_eff ln(RSS / n) + k ln(n_eff) on the fitting data (k parameters, n samples, "
                "n_eff = n (1 - r1) / (1 + r1) for the residual's lag-1 correlation r1): more parameters rank "
                "higher only if they lower the error by more than they cost; non-converged fits last")


def bic(fit: Metrics, n_parameters: int) -> float:
    """Bayesian information criterion of a least-squares fit with correlated residuals: the
    Gaussian log-likelihood and the penalty on the effective number of independent samples."""
    rho = min(max(fit.residual_lag1, 0.0), 0.99)
    n_eff = max(fit.n_samples * (1.0 - rho) / (1.0 + rho), 1.0)
    return n_eff * math.log(max(fit.rmse_nm, 1e-300) ** 2) + n_parameters * math.log(n_eff)


def ranking_table(results: dict[str, Identification]) -> pd.DataFrame:
    """One row per family, best first by :data:`RANKING_RULE`; ``delta_bic`` is the distance
    to the best (above ~10: strong evidence against the family)."""
    rows = []
    for kind, r in results.items():
        rows.append({"model": kind, "n_parameters": r.n_parameters, "fit_nrmse_percent": 100 * r.fit.nrmse,
                     "holdout_nrmse_percent": 100 * r.holdout.nrmse if r.holdout else np.nan,
                     "bic": bic(r.fit, r.n_parameters),
                     "fit_time_s": r.time_s, "evaluations": r.evaluations, "converged": r.converged})
    table = pd.DataFrame(rows)
    if table.empty:
        return table
    table["_rank"] = ~table["converged"]
    table = table.sort_values(["_rank", "bic"]).drop(columns="_rank").reset_index(drop=True)
    table.insert(5, "delta_bic", table["bic"] - table["bic"].iloc[0])
    table.index = table.index + 1
    return table


def record_table(results: dict[str, Identification], segments: list[Segment]) -> pd.DataFrame:
    """Seed 000 Fig. 8 as a table: per record and model, the RMSE as percent of the largest
    |torque| of all records (8b) and relative to the largest RMSE of that record over the
    models (8a)."""
    peak = max(float(np.nanmax(np.abs(s.torque_nm))) for s in segments)
    rows = []
    for kind, r in results.items():
        predictions = r.predict(segments)
        for seg, pred in zip(segments, predictions):
            m = metrics([seg], [pred])
            rows.append({"record": seg.name, "model": kind, "rmse_nm": m.rmse_nm, "nrmse_percent": 100 * m.rmse_nm / peak})
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
    """Seed 000 Fig. 8 (bars of the per-record RMSE, relative to the largest and in percent of
    the largest torque) and the hysteresis loops of every model overlaid on ``segment``."""
    plt = _pyplot()
    out = make_folder(out_dir)
    paths = []
    fig, axes = plt.subplots(1, 2, figsize=(13, 4.5))
    for ax, col, title in ((axes[0], "rmse_over_max_rmse", "RMSE / max RMSE of the record"),
                           (axes[1], "nrmse_percent", "RMSE (% of max |torque|)")):
        pivot = records.pivot(index="record", columns="model", values=col)
        pivot.plot.bar(ax=ax, rot=30)
        ax.set_title(title)
        ax.set_xlabel("")
    fig.suptitle("models compared per record (seed 000 Fig. 8)")
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
