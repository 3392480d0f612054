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
    if result.search:
        lines.append(f"global search: {result.search['candidates']} candidates over the bounds, least squares from "
                     f"the best {result.search['local_fits']}")
    if result.verdict:
        lines.append(result.verdict.text())
    lines.append("per test (angle nRMSE %):")
    for r in result.fit_error["per_test"] + (result.holdout_error["per_test"] if result.holdout_error else []):
        held = " (held out)" if r["file"] in result.tests_held_out else ""
        lines.append(f"  {r['file']}: J {r['inertia_kgm2']:.4g} kg*m^2, {r['amplitude_deg']:.3g} deg, "
                     f"{r['frequency_hz']:.3g} Hz: {100 * r['angle_nrmse']:.3f}{held}")
    for e in result.tests_excluded:
        lines.append(f"  excluded {e['file']}: {e['reason']}")
    return "\n".join(lines)


def servo_prediction(result: Any, decays: list, paths: list[str], settings: Any) -> tuple[Any, str]:
    """The fitted model on a servo grid over the tested amplitude and frequency range (K', loss
    factor, the drop-tower-equivalent damping ratio), next to the drop tower's map (seed 004
    eq. 19-20 fitted to the first-cycle evaluations of the same logs) at the same points.
    Returns the table and a note on the map."""
    import pandas as pd

    from droptower.extract.files import Settings, extract_file, result_row
    from droptower.identify.dropfit import servo_grid, tested_range
    from droptower.maps.fit import fit_map

    (a0, a1), (f0, f1) = tested_range(decays)
    grid = servo_grid(result.coupling(), np.geomspace(a0, a1, 5), np.geomspace(f0, f1, 4))
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
    return table, f"drop-tower map (seed 004 eq. 19-20) from {len(rows)} first-cycle evaluations"


def plot_servo_prediction(table: Any, out_dir: str) -> Path:
    """Stiffness and damping over amplitude, one line per frequency: the fitted model on the
    servo bench (solid) and the drop tower's map (dashed)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    fig, (ax_k, ax_d) = plt.subplots(1, 2, figsize=(12, 4.5))
    for i, (f, part) in enumerate(table.groupby("frequency_hz")):
        color = f"C{i}"
        ax_k.plot(part["amplitude_deg"], part["model_storage_stiffness_nm_per_deg"], color=color,
                  label=f"model K', {f:.3g} Hz")
        ax_d.plot(part["amplitude_deg"], part["model_drop_tower_equivalent_damping_ratio"], color=color,
                  label=f"model, {f:.3g} Hz")
        if "map_stiffness_nm_per_deg" in part:
            ax_k.plot(part["amplitude_deg"], part["map_stiffness_nm_per_deg"], "--", color=color, label=f"map, {f:.3g} Hz")
            ax_d.plot(part["amplitude_deg"], part["map_damping_ratio"], "--", color=color, label=f"map, {f:.3g} Hz")
    ax_k.set_ylabel("stiffness (N*m/deg)")
    ax_d.set_ylabel("drop-tower damping ratio d (model: equivalent to its loss factor)")
    for ax in (ax_k, ax_d):
        ax.set_xlabel("amplitude (deg)")
        ax.legend(fontsize=7)
    fig.suptitle("fitted model on the servo bench (solid) vs the drop tower's map (dashed)")
    fig.tight_layout()
    path = out / "identify_drop_servo_prediction.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def prepare(data: tuple[str, ...], kind: str | None, channels: tuple[str, ...], init: Any, template: str | None,
            holdout_fraction: float, rig: str | None, inertia_kgm2: float | None,
            lever_length_m: float | None) -> tuple[list, list, Any, dict, Any]:
    """The campaign's decays, the excluded logs (reported on stderr), the fit settings, the
    family options and the read settings, from the command line's options."""
    from droptower.identify.dropfit import DropFitSettings
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
    return decays, excluded, settings, options, read


def run(data: tuple[str, ...], kind: str, channels: tuple[str, ...], init: Any, template: str | None,
        holdout_fraction: float, rig: str | None, inertia_kgm2: float | None, lever_length_m: float | None,
        out: str | None, as_json: bool, plot_dir: str | None, predict_servo: str | None,
        accept_poor: bool = False) -> None:
    from droptower.identify.dropfit import identify_drops
    from droptower.identify.verdict import EXIT_POOR_FIT

    decays, excluded, settings, options, read = prepare(data, kind, channels, init, template, holdout_fraction, rig,
                                                        inertia_kgm2, lever_length_m)
    progress(f"identify: fitting {kind} to {len(decays)} drop test(s) ...")
    result = identify_drops(kind, decays, excluded=excluded, settings=settings, init=init.initial, bounds=init.bounds,
                            options=options)
    poor = result.verdict is not None and result.verdict.poor and not accept_poor
    if result.converged and out and not poor:
        result.coupling_file = str(out)
    click.echo(json.dumps(result.as_dict(), indent=1) if as_json else drop_report_text(result))
    if predict_servo or plot_dir:
        from droptower.io.tables import write_table

        paths = [str(p) for p in _log_paths(data)]
        table, map_note = servo_prediction(result, decays, paths, read)
        note(f"servo prediction: {map_note}")
        if predict_servo:
            note(f"servo prediction: {write_table(table, predict_servo, '--predict-servo')}")
        if plot_dir:
            note(f"plot: {plot_servo_prediction(table, plot_dir)}")
    if not result.converged:
        raise DroptowerError(f"model {kind}: the fit to the drop tests did not converge ({result.message}); "
                             "no coupling written")
    if poor:
        click.echo(f"droptower: model {kind}: poor fit ({'; '.join(result.verdict.reasons)}); no coupling written "
                   f"(--accept-poor writes it; exit code {EXIT_POOR_FIT})", err=True)
        raise click.exceptions.Exit(EXIT_POOR_FIT)
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
