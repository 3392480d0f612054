"""``droptower report``: one self-contained HTML report of a campaign folder, a results table or
a lab's folder of logs."""
from __future__ import annotations

from pathlib import Path

import click

from droptower.cli import options
from droptower.cli.options import conditions_options


@click.command("report")
@options.quiet_option
@click.argument("source", type=click.Path(path_type=Path))
@click.option("--out", type=click.Path(path_type=Path, dir_okay=False), default=None,
              help="The HTML file to write (default: DIR/report.html, or the results table's name with .html).")
@click.option("--form", type=click.Choice(["paper", "velocity", "auto"]), default="paper", show_default=True,
              help="The map form (as droptower map --form).")
@click.option("--channel", "channel_specs", multiple=True, metavar="ROLE=NAME[:UNIT]",
              help="Channel mapping for reading real logs again (as droptower extract --channel).")
@click.option("--rig", default=None,
              help="Rig TOML (or shipped preset) of real logs: lever length, laser radius, fixtures (as extract --rig).")
@click.option("--sensor-radius-m", type=float, default=None,
              help="Laser spot radius in m for a distance channel of real logs (over the rig's).")
@click.option("--inertia-kgm2", type=float, default=None,
              help="Rotating inertia J in kg*m^2 of every log (a lab's logs; else their metadata, --conditions or a "
                   "rig with a single fixture).")
@click.option("--lever-length-m", type=float, default=None,
              help="Lever arm L in m of a lab's logs (over their metadata and the rig's).")
@conditions_options
@click.option("--model-map", "model_map_path", type=click.Path(path_type=Path, dir_okay=False), default=None,
              help="Also show the model-based map (model_map.json from `droptower map --model-out`) beside the "
                   "paper's, both validated against the servo bench: a campaign's own coupling on the virtual "
                   "bench, or --servo-results.")
@click.option("--servo-results", type=click.Path(path_type=Path, dir_okay=False), default=None,
              help="With --model-map: the lab's measured servo results (as validate --servo-results) to validate "
                   "both routes against.")
@click.option("--servo-column", "servo_columns", multiple=True, metavar="NAME=SOURCE[:UNIT]",
              help="Map a column of --servo-results (as validate --servo-column); repeatable.")
def report(source: Path, out: Path | None, form: str, channel_specs: tuple[str, ...], rig: str | None,
           sensor_radius_m: float | None, inertia_kgm2: float | None, lever_length_m: float | None,
           conditions: str | None, condition_columns: tuple[str, ...],
           conditions_pattern: str | None, model_map_path: Path | None, servo_results: Path | None,
           servo_columns: tuple[str, ...]) -> None:
    """Write one HTML report (opens offline, no server) of SOURCE: a `droptower campaign` folder,
    a results table from `droptower extract --out` with its logs, or a lab's folder of logs
    (extracted here, with --rig, --conditions, --channel, --sensor-radius-m).

    Summary of the run, failures and flags with their reasons, the map with its coefficients and
    fit and cross-validated errors, a sortable table of the tests, and per test the measured angle
    and torque with the decay fit and its window (the logs are extracted again for the plots).
    Every test the map uses has its decay drawn: if one cannot be drawn (its log missing, or the
    geometry to read it: --rig, --sensor-radius-m, --conditions), nothing is written and the exit
    code is 2, with the reason. A log of a folder that cannot be evaluated is named on one line,
    the page lists it, and the exit code is 2.

    \b
    Examples:
      droptower report runs/table2                      # -> runs/table2/report.html
      droptower report results.csv --out report.html --form auto
      droptower report lab/ --rig lab_rig.toml --conditions lab/conditions.xlsx --channel distance=Weg:mm \\
          --model-map model_map.json --servo-results bench.csv --out lab_report.html
    """
    from droptower.cli.map_cmd import failed_logs
    from droptower.errors import DroptowerError, check_positive
    from droptower.io.mapping import parse_channel_options
    from droptower.io.table_reader import parse_column_options
    from droptower.maps.fromlogs import is_log_folder, log_files
    from droptower.report import write_report
    from droptower.report.run import load_run

    check_positive(sensor_radius_m, "--sensor-radius-m")
    check_positive(inertia_kgm2, "--inertia-kgm2")
    check_positive(lever_length_m, "--lever-length-m")
    if servo_results is not None and model_map_path is None:
        raise DroptowerError("--servo-results validates the two routes of --model-map: give --model-map too")
    if servo_columns and servo_results is None:
        raise DroptowerError("--servo-column maps the columns of --servo-results, which is not given")
    logs = log_files(source, exclude=[p for p in (conditions, rig) if p]) if is_log_folder(source) else []
    rig_config = options.rig_for_logs(rig, [str(p) for p in logs])
    conditions_table = options.conditions_from_cli(conditions, condition_columns, conditions_pattern, rig_config)
    channels = parse_channel_options(channel_specs)
    run = load_run(source, rig=rig_config, roles=channels, sensor_radius_m=sensor_radius_m, conditions=conditions_table,
                   inertia_kgm2=inertia_kgm2, lever_length_m=lever_length_m)
    failed = failed_logs(run.table) if run.kind == "log folder" else 0
    if conditions_table is not None and logs:
        for name in conditions_table.unmatched(logs):
            click.echo(f"droptower: warning: {conditions_table.source}: row '{name}' names no log of {source}", err=True)
    extra = None
    if model_map_path is not None:
        extra = [_routes(source, run, model_map_path, form, servo_results,
                         parse_column_options(servo_columns, "--servo-column"))]
    path = write_report(source, out, form=form, channels=channels, extra_sections=extra,
                        progress=options.progress_disabled() is None, run=run)
    options.wrote(path, f"HTML report, {path.stat().st_size / 1e6:.1f} MB")
    if failed:  # the page lists them too; the run was not complete
        click.echo(f"droptower: {failed} log(s) could not be evaluated (listed above); exit code 2", err=True)
        raise click.exceptions.Exit(2)


def _routes(source: Path, run, model_map_path: Path, form: str, servo_results: Path | None,
            servo_columns: dict[str, str]) -> tuple[str, str]:
    """The two-routes section, validated against the lab's servo results or, for a campaign
    folder, the virtual bench on its own coupling."""
    from droptower.campaign.folder import saved_inputs
    from droptower.compare.model_map import ModelMap
    from droptower.report.routes import routes_report_section

    coupling = None
    if servo_results is None:
        coupling = saved_inputs(source).get("coupling") if run.kind == "campaign" else None
        if coupling is None:
            options.note("note: no campaign coupling to run the servo sweeps on and no --servo-results: the routes "
                         "are shown, not validated")
    return routes_report_section(source, ModelMap.from_json(model_map_path), form, coupling,
                                 servo_results=servo_results, servo_columns=servo_columns, table=run.table)
