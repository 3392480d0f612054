"""``droptower validate``: a characteristic map against servo-hydraulic sweeps (Rapp et al. 2022, Fig. 14)
and, optionally, against a measured map such as Rapp et al. 2022, Table 4."""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import click

from droptower.cli.options import conditions_options, quiet_option, wrote
from droptower.cli.servo_records_cmd import name_servo_source, servo_record_options, servo_records_table
from droptower.configs import DEFAULT_COUPLING


@click.command()
@quiet_option
@click.option("--map", "map_path", type=click.Path(path_type=Path), required=True,
              help="The map (map.json from `droptower map --out`).")
@click.option("--coupling", default=DEFAULT_COUPLING, show_default=True,
              help="Coupling (TOML file or preset) to run the sweeps on the virtual servo bench.")
@click.option("--servo-results", type=click.Path(path_type=Path), default=None,
              help="Measured servo results (a table: CSV with any delimiter and decimal comma, Parquet, Excel) "
                   "instead of the virtual bench: amplitude_deg, "
                   "frequency_hz, a stiffness column (storage_stiffness_nm_per_deg, ...), a damping column "
                   "(drop_tower_equivalent_damping_ratio, loss_factor, loss_angle_deg or relative_damping_psi), "
                   "optional sweep.")
@click.option("--servo-column", "servo_columns", multiple=True, metavar="NAME=SOURCE[:UNIT]",
              help="Map a column of --servo-results to a name above (e.g. loss_factor=Verlustfaktor, "
                   "amplitude_deg=Amp:rad); repeatable. Lab names (Amplitude [°], Frequenz [Hz], Verlustfaktor, "
                   "Speichersteifigkeit [Nm/°]) are found without it.")
@click.option("--reference", type=click.Path(path_type=Path), default=None,
              help="Also compare with a measured map table (e.g. Rapp et al. 2022, Table 4: inertia_kgm2, amplitude_deg, "
                   "frequency_hz, stiffness_nm_per_deg, damping_ratio).")
@click.option("--results", type=click.Path(path_type=Path), default=None,
              help="With --reference: the campaign (folder or results table) whose tests are interpolated at "
                   "each reference row's case and amplitude.")
@click.option("--model-map", "model_map_path", type=click.Path(path_type=Path), default=None,
              help="Also validate the model-based map (model_map.json from `droptower map --model-out`): both "
                   "routes against the same servo points, inside and outside the paper map's hull.")
@click.option("--quick", is_flag=True, help="Fewer sweep steps (a quick check).")
@click.option("--out", type=click.Path(path_type=Path), default=None,
              help="Write validation.csv, validation_summary.json, servo_results.csv and "
                   "fig14_servo_validation.png (and the reference comparison) into this folder.")
@click.option("--table-format", type=click.Choice(["csv", "parquet", "json", "xlsx"]), default="csv",
              show_default=True, help="Format of the tables written into --out.")
@click.option("--json", "as_json", is_flag=True, help="Print the comparison as JSON.")
@click.option("--rig", default=None, help="With --results a lab's folder of logs: its rig TOML (lever length, laser "
                                          "radius, fixtures).")
@click.option("--sensor-radius-m", type=float, default=None,
              help="With --results a lab's folder of logs: the laser spot radius in m.")
@click.option("--channel", "channel_specs", multiple=True, metavar="ROLE=NAME[:UNIT]",
              help="With --results a lab's folder of logs: channel mapping (as droptower extract --channel).")
@click.option("--inertia-kgm2", type=float, default=None,
              help="With --results a lab's folder of logs: the inertia J in kg*m^2 of every log.")
@click.option("--lever-length-m", type=float, default=None,
              help="With --results a lab's folder of logs: the lever arm L in m.")
@conditions_options
@servo_record_options
def validate(map_path: Path, coupling: str, servo_results: Path | None, servo_columns: tuple[str, ...],
             reference: Path | None,
             results: Path | None, model_map_path: Path | None, quick: bool, out: Path | None, table_format: str,
             as_json: bool, rig: str | None, sensor_radius_m: float | None, channel_specs: tuple[str, ...],
             inertia_kgm2: float | None, lever_length_m: float | None,
             conditions: str | None, condition_columns: tuple[str, ...], conditions_pattern: str | None,
             **servo_records: Any) -> None:
    """Predict the servo-hydraulic sweeps of docs/theory.md#servo from the map and compare: frequency
    sweeps at 0.5, 1.5, 2.5 deg up to 100, 60, 20 Hz and amplitude sweeps at 1, 10, 30 Hz up to
    10, 6, 2 deg, run on the virtual servo bench with --coupling (or read from --servo-results).

    Stiffness: the map's c (= J(omega^2 + delta^2), Rapp et al. 2022, eq. 15) against the servo's storage
    stiffness K'. Damping like with like (docs/theory.md#damping-measures): the map's damping ratio (the drop tower's
    d = E_diss/E_el, eq. 16) against the servo's drop-tower-equivalent d; the loss factor and the
    relative damping psi of both are reported alongside. Deviations (map / servo - 1) are
    summarised inside and outside the drop tower's measured range.

    \b
    Examples:
      droptower validate --map map.json --coupling rapp2022_nr60 --out validation/
      droptower validate --map map.json --servo-results measured.csv --out validation/ --table-format xlsx
      droptower validate --map map.json --servo-records sweep1.csv --servo-records sweep2.csv --out validation/
    """
    from droptower.compare.validate import validate as run_validation
    from droptower.errors import DroptowerError
    from droptower.io.table_reader import parse_column_options

    if results is not None and reference is None:
        raise DroptowerError("--results needs --reference (the measured map to compare the campaign with)")
    if out is not None:
        from droptower.compare.files import output_folder

        output_folder(out, create=False)  # before the sweeps: a bad --out fails at once
    columns = parse_column_options(servo_columns, "--servo-column")
    lab = _lab_logs(results, rig, sensor_radius_m, channel_specs, conditions, condition_columns, conditions_pattern,
                    inertia_kgm2, lever_length_m)
    failed = 0
    if lab is not None:  # a lab's folder, extracted here: its failed logs named, one line each
        from droptower.cli.map_cmd import failed_logs

        failed, results = failed_logs(lab), lab
    with servo_records_table(servo_records, servo_results, out) as servo_results:
        result = run_validation(map_path, coupling, servo_results=servo_results, servo_columns=columns,
                                reference=reference, results=results, model_map=model_map_path, quick=quick)
    name_servo_source(result, servo_records)
    if out is not None:
        described = {"validation_routes": "the two routes vs the servo points",
                     "validation_model_map": f"the {result.model_route} at every servo point"}
        for path in result.write(out, table_format):
            wrote(path, described.get(path.stem, "validation"))
    if as_json:
        click.echo(json.dumps(result.to_dict(), indent=1))
    else:
        click.echo(result.summary())
    if failed:
        click.echo(f"droptower: {failed} log(s) of --results could not be evaluated (listed above); exit code 2",
                   err=True)
        raise click.exceptions.Exit(2)


def _lab_logs(results: Path | None, rig: str | None, sensor_radius_m: float | None, channel_specs: tuple[str, ...],
              conditions: str | None, condition_columns: tuple[str, ...], conditions_pattern: str | None,
              inertia_kgm2: float | None = None, lever_length_m: float | None = None):
    """--results, a lab's folder of logs, extracted with the rig, channels, laser radius and
    conditions (:func:`droptower.maps.fromlogs.results_from_logs`); None for any other --results."""
    from droptower.cli.options import conditions_from_cli, rig_for_logs
    from droptower.errors import DroptowerError, check_positive
    from droptower.io.mapping import parse_channel_options
    from droptower.maps.fromlogs import is_log_folder, log_files, results_from_logs

    folder = results is not None and is_log_folder(results)
    given = rig or sensor_radius_m or channel_specs or conditions or conditions_pattern or inertia_kgm2 or lever_length_m
    if given and not folder:
        raise DroptowerError("--rig, --sensor-radius-m, --channel, --inertia-kgm2, --lever-length-m and --conditions "
                             "read the logs of --results: give --results a folder of logs")
    if not folder:
        return None
    for value, flag in ((sensor_radius_m, "--sensor-radius-m"), (inertia_kgm2, "--inertia-kgm2"),
                        (lever_length_m, "--lever-length-m")):
        check_positive(value, flag)
    logs = log_files(results, exclude=[p for p in (conditions, rig) if p])
    config = rig_for_logs(rig, [str(p) for p in logs])
    table = conditions_from_cli(conditions, condition_columns, conditions_pattern, config)
    for name in table.unmatched(logs) if table is not None else []:
        click.echo(f"droptower: warning: {table.source}: row '{name}' names no log of {results}", err=True)
    return results_from_logs(logs, rig=config, roles=parse_channel_options(channel_specs),
                             sensor_radius_m=sensor_radius_m, conditions=table, inertia_kgm2=inertia_kgm2,
                             lever_length_m=lever_length_m)
