"""``droptower identify --from-drop-tests``: a coupling model from drop-test logs alone.

Kept apart from the servo-record path of ``identify`` (:mod:`.identify_cmd` dispatches here);
a thin layer over :mod:`droptower.identify.drop_campaign` and :mod:`droptower.identify.dropreport`.
"""
from __future__ import annotations

import json
from typing import Any

import click

from droptower.cli.flags import cli_text
from droptower.cli.options import note, progress, wrote
from droptower.errors import DroptowerError

#: excluded tests named on stderr without --verbose (the rest are counted)
EXCLUDED_SHOWN = 5


def prepare(data: tuple[str, ...], kind: str | None, channels: tuple[str, ...], init: Any, template: str | None,
            holdout_fraction: float, rig: str | None, inertia_kgm2: float | None,
            lever_length_m: float | None, verbose: bool = False, *, sensor_radius_m: float | None = None,
            conditions: tuple[str | None, tuple[str, ...], str | None] = (None, (), None)) -> Any:
    """The campaign's logs read (:func:`~droptower.identify.drop_campaign.read_drop_tests`) from the
    command line's options, the excluded logs reported on stderr (the first few, or with
    ``verbose`` all). ``conditions``: (--conditions, --condition-column, --conditions-from-names);
    a lab's folder of logs is searched for logs, the conditions table beside them left out."""
    from pathlib import Path

    from droptower.cli.options import conditions_from_cli, rig_for_logs
    from droptower.errors import check_positive
    from droptower.identify.drop_campaign import read_drop_tests
    from droptower.io import parse_channel_options
    from droptower.maps.fromlogs import log_files

    check_positive(sensor_radius_m, "--sensor-radius-m")
    table, columns, pattern = conditions
    files: list[str | Path] = []
    for d in data:
        p = Path(d)
        lab = p.is_dir() and not (p / "logs").is_dir()  # a lab's folder of logs, not a campaign's
        files += log_files(p, exclude=[x for x in (table, rig) if x]) if lab else [d]
    rig_config = rig_for_logs(rig, [str(f) for f in files if Path(f).is_file()])
    conditions_table = conditions_from_cli(table, columns, pattern, rig_config)
    data = tuple(files)
    rig = rig_config if rig_config is not None else rig
    results_table = _results_table(data)
    if results_table is not None:  # a results table with its logs: each log read with its row's inertia
        from droptower.compare.model_map import read_logs_for_model

        campaign = read_logs_for_model(data[0], kind, template=template, rig=rig, roles=parse_channel_options(channels),
                                       sensor_radius_m=sensor_radius_m, conditions=conditions_table, table=results_table,
                                       holdout_fraction=holdout_fraction, options=init.options)
    else:
        campaign = read_drop_tests(data, family=kind, options=init.options, template=template,
                                   holdout_fraction=holdout_fraction, rig=rig, inertia_kgm2=inertia_kgm2,
                                   lever_length_m=lever_length_m, roles=parse_channel_options(channels),
                                   sensor_radius_m=sensor_radius_m, conditions=conditions_table)
    excluded = campaign.excluded
    for e in excluded if verbose else excluded[:EXCLUDED_SHOWN]:
        click.echo(f"droptower: excluded {e['file']}: {cli_text(e['reason'])}", err=True)
    if len(excluded) > EXCLUDED_SHOWN and not verbose:
        click.echo(f"droptower: excluded {len(excluded) - EXCLUDED_SHOWN} more test(s) (--verbose names them)", err=True)
    return campaign


def _results_table(data: tuple) -> Any:
    """The results table DATA is (one table from ``extract --out`` whose ``file`` column names
    its logs), or None for logs and folders."""
    from pathlib import Path

    from droptower.maps import read_results

    if len(data) != 1 or not Path(data[0]).is_file() or Path(data[0]).suffix.lower() not in (".csv", ".parquet",
                                                                                              ".xlsx", ".json"):
        return None
    try:
        table = read_results(data[0])
    except DroptowerError:
        return None  # a log, not a results table
    return table if "file" in table.columns else None


def run(data: tuple[str, ...], kind: str, channels: tuple[str, ...], init: Any, template: str | None,
        holdout_fraction: float, rig: str | None, inertia_kgm2: float | None, lever_length_m: float | None,
        out: str | None, as_json: bool, plot_dir: str | None, predict_servo: str | None,
        verbose: bool = False, accept_poor: bool = False, *, sensor_radius_m: float | None = None,
        conditions: tuple[str | None, tuple[str, ...], str | None] = (None, (), None),
        uncertainty_specs: tuple[str, ...] = ()) -> None:
    from droptower.identify.dropreport import drop_report_text, plot_servo_prediction, servo_prediction
    from droptower.identify.drop_campaign import identify_from_drop_tests
    from droptower.identify.verdict import EXIT_POOR_FIT

    campaign = prepare(data, kind, channels, init, template, holdout_fraction, rig, inertia_kgm2, lever_length_m,
                       verbose, sensor_radius_m=sensor_radius_m, conditions=conditions)
    progress(f"identify: fitting {kind} to {len(campaign.decays)} drop test(s) ...")
    result = identify_from_drop_tests(campaign, kind, init=init.initial, bounds=init.bounds)
    poor = result.verdict is not None and result.verdict.poor and not accept_poor
    if result.converged and out and not poor:
        result.coupling_file = str(out)
    budget = _budget(result, campaign, rig, uncertainty_specs) if result.converged else None
    doc = result.to_dict() if as_json else None
    if doc is not None and budget is not None:
        from droptower.jsonsafe import json_safe

        doc["uncertainty"] = json_safe({"coverage_factor": 2.0, "parameters": budget.to_dict(orient="records")})
    click.echo(json.dumps(doc, indent=1) if as_json else cli_text(drop_report_text(result, verbose)))
    if budget is not None and not as_json:
        click.echo(_budget_text(budget))
    if predict_servo or plot_dir:
        from droptower.io.tables import write_table

        table, map_note = servo_prediction(result, campaign)
        note(f"servo prediction: {cli_text(map_note)}")
        if predict_servo:
            wrote(write_table(table, predict_servo, '--predict-servo'), f"servo prediction, {len(table)} points")
        if plot_dir:
            wrote(plot_servo_prediction(table, plot_dir), "servo prediction vs the drop tower's map")
    if not result.converged:
        raise DroptowerError(f"family {kind}: the fit to the drop tests did not converge ({result.message}); "
                             "no coupling written")
    if poor:
        click.echo(f"droptower: family {kind}: poor fit ({'; '.join(result.verdict.reasons)}); no coupling written "
                   f"(--accept-poor writes it; exit code {EXIT_POOR_FIT})", err=True)
        raise click.exceptions.Exit(EXIT_POOR_FIT)
    if out:
        result.write_coupling(out)
        wrote(out, f"coupling {kind}, for simulate, campaign, servo")


def _budget(result: Any, campaign: Any, rig: str | None, specs: tuple[str, ...]) -> Any:
    """The parameters' budget with the rig's input uncertainties (--uncertainty over the rig
    file's [uncertainty]; :func:`droptower.uncertainty.route.route_parameter_budget`), or None
    where none is given."""
    from droptower.cli.options import note_uncertainty, uncertainty_from_cli
    from droptower.uncertainty.route import nominal_geometry, route_input_values, route_parameter_budget

    if not specs and rig is None:
        return None
    if rig is not None:  # its geometry was printed when the logs were read
        from droptower.rig.config import load_rig

        rig = load_rig(rig)
    uncertainty = uncertainty_from_cli(specs, rig)
    if uncertainty is None:
        return None
    note_uncertainty(uncertainty)
    lever, laser = nominal_geometry(campaign.decays, campaign.read)
    values = route_input_values(result, campaign.decays, campaign.settings, uncertainty, lever_length_m=lever,
                                laser_radius_m=laser)
    return route_parameter_budget(result, values)


def _budget_text(budget: Any) -> str:
    """One line per parameter: value, u_fit, u_inputs, U95 (k = 2) and the dominant term."""
    lines = ["uncertainty (GUM; U95 = 2*u_c, u_c^2 = u_fit^2 + the inputs' shares^2):"]
    for _, r in budget.iterrows():
        lines.append(f"  {r['parameter']}: {r['value']:.6g} +- {r['U95']:.3g} (U95; fit {r['u_fit']:.3g}, inputs "
                     f"{r['u_inputs']:.3g}; dominant: {r['dominant']})")
    return "\n".join(lines)
