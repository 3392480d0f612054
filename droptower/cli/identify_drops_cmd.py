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

from droptower.cli.options import note, progress, wrote
from droptower.errors import DroptowerError, make_folder
from droptower.cli.flags import cli_text


#: excluded tests named on stderr without --verbose (the rest are counted)
EXCLUDED_SHOWN = 5


def drop_report_text(result: Any, verbose: bool = False) -> str:
    """A human-readable report of a drop-test identification; ``verbose``: a line per test."""
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
    per_test = result.fit_error["per_test"] + (result.holdout_error["per_test"] if result.holdout_error else [])
    if not verbose:
        worst = max(per_test, key=lambda r: r["angle_nrmse"])
        lines.append(f"per test: {len(per_test)} test(s), worst angle nRMSE {100 * worst['angle_nrmse']:.3f} % "
                     f"({worst['file']}); --verbose lists every test")
        return "\n".join(lines)
    lines.append("per test (angle nRMSE %):")
    for r in per_test:
        held = " (held out)" if r["file"] in result.tests_held_out else ""
        lines.append(f"  {r['file']}: J {r['inertia_kgm2']:.4g} kg*m^2, {r['amplitude_deg']:.3g} deg, "
                     f"{r['frequency_hz']:.3g} Hz: {100 * r['angle_nrmse']:.3f}{held}")
    for e in result.tests_excluded:
        lines.append(f"  excluded {e['file']}: {cli_text(e['reason'])}")
    return "\n".join(lines)


def servo_prediction(result: Any, decays: list, paths: list[str], settings: Any) -> tuple[Any, str]:
    """The fitted model on a servo grid over the tested amplitude and frequency range (K', loss
    factor, the drop-tower-equivalent damping ratio), next to the drop tower's map (Rapp et al. 2022,
    eq. 19-20 fitted to the first-cycle evaluations of the same logs) at the same points.
    Returns the table and a note on the map."""
    import pandas as pd

    from droptower.extract.files import Settings, extract_file, result_row
    from droptower.identify.dropfit import servo_grid, tested_grid
    from droptower.maps.fit import fit_map

    grid = servo_grid(result.coupling(), *tested_grid(decays))
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
        return table, f"no drop-tower map: {cli_text(exc.problem)}"
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


def servo_prediction_figure(table: Any) -> Any:
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


def plot_servo_prediction(table: Any, out_dir: str) -> Path:
    """:func:`servo_prediction_figure` as ``identify_drop_servo_prediction.png`` in ``out_dir``."""
    from droptower.io.droptower_log import save_figure

    return save_figure(servo_prediction_figure(table), Path(out_dir) / "identify_drop_servo_prediction.png", 110)


def prepare(data: tuple[str, ...], kind: str | None, channels: tuple[str, ...], init: Any, template: str | None,
            holdout_fraction: float, rig: str | None, inertia_kgm2: float | None,
            lever_length_m: float | None, verbose: bool = False) -> tuple[list, list, Any, dict, Any]:
    """The campaign's decays, the excluded logs (reported on stderr: the first few, or with
    ``verbose`` all), the fit settings, the family options and the read settings, from the
    command line's options."""
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
        defaults["sensor_radius_m"] = config.sensors.laser.radius_m
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
    for e in excluded if verbose else excluded[:EXCLUDED_SHOWN]:
        click.echo(f"droptower: excluded {e['file']}: {cli_text(e['reason'])}", err=True)
    if len(excluded) > EXCLUDED_SHOWN and not verbose:
        click.echo(f"droptower: excluded {len(excluded) - EXCLUDED_SHOWN} more test(s) (--verbose names them)", err=True)
    return decays, excluded, settings, options, read


def run(data: tuple[str, ...], kind: str, channels: tuple[str, ...], init: Any, template: str | None,
        holdout_fraction: float, rig: str | None, inertia_kgm2: float | None, lever_length_m: float | None,
        out: str | None, as_json: bool, plot_dir: str | None, predict_servo: str | None,
        verbose: bool = False, accept_poor: bool = False) -> None:
    from droptower.identify.dropfit import identify_drops
    from droptower.identify.verdict import EXIT_POOR_FIT

    decays, excluded, settings, options, read = prepare(data, kind, channels, init, template, holdout_fraction, rig,
                                                        inertia_kgm2, lever_length_m, verbose)
    progress(f"identify: fitting {kind} to {len(decays)} drop test(s) ...")
    result = identify_drops(kind, decays, excluded=excluded, settings=settings, init=init.initial, bounds=init.bounds,
                            options=options)
    poor = result.verdict is not None and result.verdict.poor and not accept_poor
    if result.converged and out and not poor:
        result.coupling_file = str(out)
    click.echo(json.dumps(result.as_dict(), indent=1) if as_json else drop_report_text(result, verbose))
    if predict_servo or plot_dir:
        from droptower.io.tables import write_table

        paths = [str(p) for p in _log_paths(data)]
        table, map_note = servo_prediction(result, decays, paths, read)
        note(f"servo prediction: {map_note}")
        if predict_servo:
            wrote(write_table(table, predict_servo, '--predict-servo'), f"servo prediction, {len(table)} points")
        if plot_dir:
            wrote(plot_servo_prediction(table, plot_dir), "servo prediction vs the drop tower's map")
    if not result.converged:
        raise DroptowerError(f"model {kind}: the fit to the drop tests did not converge ({result.message}); "
                             "no coupling written")
    if poor:
        click.echo(f"droptower: model {kind}: poor fit ({'; '.join(result.verdict.reasons)}); no coupling written "
                   f"(--accept-poor writes it; exit code {EXIT_POOR_FIT})", err=True)
        raise click.exceptions.Exit(EXIT_POOR_FIT)
    if out:
        _write(result, out, len(result.tests_used))
        wrote(out, f"coupling {kind}, for simulate, campaign, servo")


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
    make_folder(path.parent)
    path.write_text(coupling_to_toml(c))
    load_coupling(path)  # what is written must read back
