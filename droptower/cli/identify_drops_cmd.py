"""``droptower identify --from-drop-tests``: a coupling model from drop-test logs alone.

Kept apart from the servo-record path of ``identify`` (:mod:`.identify_cmd` dispatches here).
"""
from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import click
import numpy as np

from droptower.cli.options import note, progress
from droptower.errors import DroptowerError


def drop_report_text(result: Any) -> str:
    """A human-readable report of a drop-test identification."""
    lines = [f"model {result.model} from {len(result.tests_used)} drop test(s) "
             f"(+{len(result.tests_held_out)} held out, {len(result.tests_excluded)} excluded): "
             f"{'converged' if result.converged else 'NOT CONVERGED: ' + result.message}"]
    names = result.family.names
    width = max(len(n) for n in names)
    for n, v, s in zip(names, result.values, result.std_error):
        unc = f" +- {s:.3g}" if math.isfinite(s) else " (fixed)"
        lines.append(f"  {n:<{width}} = {v:.6g}{unc}{'  (at bound)' if n in result.at_bounds else ''}")
    for n, v in result.family.derived(result.values).items():
        lines.append(f"  {n:<{width}} = {float(v):.6g}  (derived)")
    for combo in result.non_identifiable:
        lines.append("  not identifiable (the fit is flat along): "
                     + " ".join(f"{w:+.3g}*z({n})" for n, w in combo.items()) + "  (z: ln value or value/scale)")
    for label, err in (("fit", result.fit_error), ("holdout", result.holdout_error)):
        if err:
            lines.append(f"{label + ':':<8} angle nRMSE {100 * err['angle_nrmse']:.3f} % (max {100 * err['angle_nrmse_max']:.3f} %)"
                         + (f", torque nRMSE {100 * err['torque_nrmse']:.3f} %" if "torque_nrmse" in err else "")
                         + f" over {err['tests']} test(s)")
    sources = sorted({r["rate_source"] for r in result.fit_error["per_test"]})
    lines.append(f"initial rate from: {', '.join(sources)} (impact_force: L * impulse / J; angle_slope: the angle's "
                 "slope after the onset)")
    lines.append(f"effort:  {result.evaluations} model evaluations, {result.nfev} optimiser steps, {result.wall_s:.2f} s")
    lines.append("per test (angle nRMSE %):")
    for r in result.fit_error["per_test"] + (result.holdout_error["per_test"] if result.holdout_error else []):
        held = " (held out)" if r["file"] in result.tests_held_out else ""
        lines.append(f"  {r['file']}: J {r['inertia_kgm2']:.4g} kg*m^2, {r['amplitude_deg']:.3g} deg, "
                     f"{r['frequency_hz']:.3g} Hz: {100 * r['angle_nrmse']:.3f}{held}")
    for e in result.tests_excluded:
        lines.append(f"  excluded {e['file']}: {e['reason']}")
    return "\n".join(lines)


def servo_prediction(result: Any, decays: list, paths: list[str], settings: Any) -> Any:
    """Per used test: what the drop tower measured (the first-cycle evaluation of seed 004 eq.
    15-16, i.e. the map's data) next to the fitted model's servo K' and loss factor at the
    test's amplitude and frequency."""
    import pandas as pd

    from droptower.extract.files import Settings, extract_file
    from droptower.identify.dropfit import servo_grid

    coupling = result.coupling()
    rows = []
    by_name = {Path(p).name: p for p in paths}
    for d in decays:
        row = {"file": d.name, "inertia_kgm2": d.inertia_kgm2, "amplitude_deg": math.degrees(d.amplitude_rad),
               "frequency_hz": d.frequency_hz}
        try:
            _, ex = extract_file(by_name[d.name], Settings(roles=settings.roles, defaults=settings.defaults))
            got = ex.as_dict()
            row["drop_tower_stiffness_nm_per_deg"] = got.get("stiffness_nm_per_deg")
            row["drop_tower_loss_factor"] = got.get("loss_factor")
        except (DroptowerError, KeyError):
            pass
        model = servo_grid(coupling, np.array([d.amplitude_rad]), np.array([d.frequency_hz])).iloc[0]
        row["model_storage_stiffness_nm_per_deg"] = float(model["storage_stiffness_nm_per_deg"])
        row["model_loss_factor"] = float(model["loss_factor"])
        rows.append(row)
    return pd.DataFrame(rows)


def plot_servo_prediction(table: Any, out_dir: str) -> Path:
    """K' and loss factor over amplitude: the drop tower's first-cycle values and the model's."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    fig, (ax_k, ax_e) = plt.subplots(1, 2, figsize=(12, 4.5))
    for ax, drop, model, label in ((ax_k, "drop_tower_stiffness_nm_per_deg", "model_storage_stiffness_nm_per_deg",
                                    "stiffness (N*m/deg)"), (ax_e, "drop_tower_loss_factor", "model_loss_factor",
                                                             "loss factor")):
        if drop in table:
            ax.scatter(table["amplitude_deg"], table[drop], marker="o", label="drop tower (first cycle)")
        sc = ax.scatter(table["amplitude_deg"], table[model], c=table["frequency_hz"], marker="x",
                        label="fitted model, servo K' / eta")
        ax.set_xlabel("amplitude (deg)")
        ax.set_ylabel(label)
        ax.legend()
    fig.colorbar(sc, ax=ax_e, label="frequency (Hz)")
    fig.tight_layout()
    path = out / "identify_drop_servo_prediction.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def run(data: tuple[str, ...], kind: str, channels: tuple[str, ...], init: Any, template: str | None,
        holdout_fraction: float, rig: str | None, inertia_kgm2: float | None, lever_length_m: float | None,
        out: str | None, as_json: bool, plot_dir: str | None, predict_servo: str | None) -> None:
    from droptower.identify.dropfit import DropFitSettings, identify_drops
    from droptower.identify.droplogs import ReadSettings, read_decays
    from droptower.io import parse_channel_options

    options = dict(init.options)
    if template is not None:
        options["template"] = template
    if kind == "template" and "template" not in options:
        raise DroptowerError("--model template needs --template COUPLING (a preset name or a coupling TOML)")
    defaults: dict[str, float] = {}
    conditioning = (2.0, 30.0)
    if rig is not None:
        from droptower.rig.config import load_rig

        config = load_rig(rig)
        defaults["lever_length_m"] = config.lever_length_m
        if len(config.inertias_kgm2) == 1:
            defaults["inertia_kgm2"] = config.inertias_kgm2[0]
        conditioning = (config.simulation.preload_ramp_s, config.simulation.preload_hold_s)
    fit_keys = {"substeps", "torque_weight", "max_nfev", "seed", "conditioning"}
    fit_opts = {k: options.pop(k) for k in list(options) if k in fit_keys}
    options.pop("skip_s", None)
    cycles = float(options.pop("cycles", 3.0))
    rate = str(options.pop("initial_rate", "auto"))
    if rate not in ("auto", "impulse", "slope"):
        raise DroptowerError(f"option initial_rate must be auto, impulse or slope, got {rate!r}")
    if not fit_opts.pop("conditioning", True):
        conditioning = None
    settings = DropFitSettings(substeps=int(fit_opts.get("substeps", 1)),
                               torque_weight=float(fit_opts.get("torque_weight", 0.5)), conditioning=conditioning,
                               holdout_fraction=holdout_fraction, max_nfev=int(fit_opts.get("max_nfev", 0)),
                               seed=int(fit_opts.get("seed", 0)))
    read = ReadSettings(roles=parse_channel_options(channels), inertia_kgm2=inertia_kgm2, lever_length_m=lever_length_m,
                        defaults=defaults, cycles=cycles, rate=rate)
    decays, excluded = read_decays(data, read)
    for e in excluded:
        click.echo(f"droptower: excluded {e['file']}: {e['reason']}", err=True)
    progress(f"identify: fitting {kind} to {len(decays)} drop test(s) ...")
    result = identify_drops(kind, decays, excluded=excluded, settings=settings, init=init.initial, bounds=init.bounds,
                            options=options)
    if result.converged and out:
        result.coupling_file = str(out)
    click.echo(json.dumps(result.as_dict(), indent=1) if as_json else drop_report_text(result))
    if predict_servo or plot_dir:
        from droptower.io.tables import write_table

        paths = [str(p) for p in _log_paths(data)]
        table = servo_prediction(result, decays, paths, read)
        if predict_servo:
            note(f"servo prediction: {write_table(table, predict_servo, '--predict-servo')}")
        if plot_dir:
            note(f"plot: {plot_servo_prediction(table, plot_dir)}")
    if not result.converged:
        raise DroptowerError(f"model {kind}: the fit to the drop tests did not converge ({result.message}); "
                             "no coupling written")
    if out:
        _write(result, out, len(result.tests_used))
        note(f"coupling: {out}")


def _log_paths(data: tuple[str, ...]) -> list[Path]:
    files = []
    for p in map(Path, data):
        logs = p / "logs" if (p / "logs").is_dir() else p
        files += sorted(logs.iterdir()) if p.is_dir() else [p]
    return files


def _write(result: Any, out: str, n_tests: int) -> None:
    from droptower.rheology import coupling_to_toml, load_coupling

    err = result.fit_error
    quality = f"angle nRMSE {100 * err['angle_nrmse']:.2f} % on {n_tests} drop tests"
    if result.holdout_error:
        quality += f", {100 * result.holdout_error['angle_nrmse']:.2f} % on {result.holdout_error['tests']} held out"
    c = result.coupling()
    c.description = f"{c.description}. Identified by droptower identify --from-drop-tests --model {result.model} ({quality})."
    path = Path(out)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(coupling_to_toml(c))
    load_coupling(path)  # what is written must read back
