"""``droptower map``: fit the characteristic map (Rapp et al. 2022, eq. 19 and eq. 20) to a results table."""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import click

from droptower.cli import options
from droptower.cli.options import lab_log_options, quiet_option
from droptower.cli.flags import cli_text
from droptower.errors import DroptowerError


@click.command("map")
@quiet_option
@click.argument("results", type=click.Path(path_type=Path))
@click.option("--out", type=click.Path(path_type=Path, dir_okay=False), default=None,
              help="Write the map: map.json (coefficients, uncertainties, errors, range; what validate --map "
                   "reads) or the coefficient table as .csv, .parquet or .xlsx.")
@click.option("--plot", "plot_dir", type=click.Path(path_type=Path, file_okay=False), default=None,
              help="Write the paper's Fig. 10, 12 and 13 as PNG files into this folder.")
@click.option("--form", type=click.Choice(["paper", "velocity", "auto"]), default="paper", show_default=True,
              help="paper: Rapp et al. 2022, eq. 19/20; velocity: stiffness and c/d also fall with amplitude x frequency; "
                   "auto: the terms with the least cross-validated error whose coefficients are all identifiable.")
@click.option("--nested-cv", is_flag=True,
              help="With --form auto: also cross-validate the choice of terms (nested: each fold chooses without "
                   "its tests); the error to expect of auto's map on new tests. Costs ~30x the auto fit.")
@click.option("--json", "as_json", is_flag=True, help="Print the map as JSON instead of the summary.")
@options.renamed_option("--family", "--model", "model_kind", announce=True, metavar="FAMILY",
                        help="Also build the model-based map (docs/routes.md): identify FAMILY (identify "
                             "--from-drop-tests) from the campaign's logs and evaluate it on the servo bench over amplitude x frequency, with "
                   "95 % bands cluster-robust by test. RESULTS must then be a campaign folder.")
@click.option("--template", default=None, help="With --family template: the coupling whose structure is fitted.")
@click.option("--model-coupling", type=click.Path(path_type=Path, dir_okay=False), default=None,
              help="Also build the model-based map of this coupling file as it is (identify --out), or of the coupling "
                   "an identification's --json names (no bands: no covariance).")
@click.option("--accept-poor", is_flag=True,
              help="With --family: write the model-based map even if the identification is a poor fit (labelled so).")
@click.option("--model-out", type=click.Path(path_type=Path, dir_okay=False), default=None,
              help="Write the model-based map: model_map.json (what validate --model-map reads) or its grid "
                   "as .csv, .parquet or .xlsx.")
@lab_log_options
@options.uncertainty_option
def map_command(results: Path, out: Path | None, plot_dir: Path | None, form: str, nested_cv: bool,
                as_json: bool, model_kind: str | None, template: str | None, model_coupling: Path | None,
                model_out: Path | None, accept_poor: bool, rig: str | None, sensor_radius_m: float | None,
                channel_specs: tuple[str, ...], inertia_kgm2: float | None, lever_length_m: float | None,
                conditions: str | None, condition_columns: tuple[str, ...], conditions_pattern: str | None,
                uncertainty_specs: tuple[str, ...] = ()) -> None:
    """Fit stiffness c(amplitude, frequency) (eq. 19) and damping c/d(amplitude) (eq. 20),
    or another --form; the summary gives fit and cross-validated errors.

    RESULTS is a table from `droptower extract --out` (CSV, Parquet, Excel, JSON), a `droptower campaign`
    folder (its results.parquet), a lab's folder of logs (extracted first, with --rig, --conditions,
    --channel, --sensor-radius-m), or the paper's Table 4. Flagged tests (double_impact, poor_fit,
    short_window, clipping), failed logs and incomplete rows are excluded and listed; a fixture or
    condition none of whose tests is usable is named with why (for double impacts: the drop mass
    that would avoid them), and tests spanning more than 5 K of temperature are said to.

    Input uncertainties (--rig's [uncertainty] table, --uncertainty over it): the summary gains the
    expanded uncertainty (k = 2) of every coefficient, the fit's share and the inputs' together,
    each input treated as correlated across the tests that share it (one J for all tests of a
    fixture: its error does not average out with repeats); --out's coefficient table gains
    u_fit, u_<input>, u_inputs, u_c, U95 and dominant; --plot draws the map's U95 as bars
    (Fig. 12) and bands (Fig. 13). The results table needs inertia_kgm2 (which fixture),
    sample_rate_hz and sensor_radius_m for the inputs that use them.

    \b
    Examples:
      droptower map runs/table2 --out map.json --plot figs/
      droptower map results.csv --out coefficients.xlsx
      droptower map rapp2022_table4 --form auto --nested-cv
      droptower map runs/table2 --out map.json --family template --template rapp2022_nr60 --model-out model_map.json
      droptower map lab/ --rig lab_rig.toml --conditions lab/conditions.xlsx --channel distance=Weg:mm \
          --family zerodim6 --out map.json
    """
    from droptower.io.tables import check_table_path, write_table
    from droptower.maps import fit_map, select_tests
    from droptower.maps.fromlogs import is_log_folder
    from droptower.maps.nested import nested_summary

    if out is not None:
        check_table_path(out, "--out")
    if model_out is not None:
        check_table_path(model_out, "--model-out")
    if model_kind is not None and model_coupling is not None:
        raise DroptowerError("give --family (identify from the logs) or --model-coupling (a coupling as it is), not both")
    if model_out is not None and model_kind is None and model_coupling is None:
        raise DroptowerError("--model-out writes the model-based map: give --family FAMILY or --model-coupling FILE")
    if nested_cv and form != "auto":
        raise DroptowerError("--nested-cv cross-validates auto's choice of terms: use it with --form auto")
    geometry = {"inertia_kgm2": inertia_kgm2, "lever_length_m": lever_length_m}
    table, rig_config, conditions_table = _read_source(results, rig, sensor_radius_m, channel_specs, conditions,
                                                       condition_columns, conditions_pattern, model_kind is not None,
                                                       geometry)
    failed = failed_logs(table) if is_log_folder(results) else 0
    from droptower.maps.coverage import coverage_notes

    try:
        fit = fit_map(table, source=results, form=form)
    except DroptowerError:
        # no map: still say which fixtures and conditions dropped out, and why (before the error)
        for line in coverage_notes(table, *select_tests(table, results), rig=rig_config):
            click.echo(f"droptower: not covered: {line}", err=True)
        raise
    fit.coverage = tuple(coverage_notes(table, *select_tests(table, results), rig=rig_config))
    input_u = options.uncertainty_from_cli(uncertainty_specs, rig_config)
    bands = None
    if input_u is not None:
        from droptower.uncertainty import map_uncertainty

        bands = map_uncertainty(table, input_u, map_fit=fit)
        fit.input_uncertainty = input_u.model_dump(exclude_none=True)  # stored in map.json: validate reuses them
    if out is not None and out.suffix.lower() == ".json":
        fit.to_json(out)
        options.wrote(out, f"the map: {len(fit.form.units)} coefficients, errors, range; validate --map reads it")
    elif out is not None:
        coefficients = fit.coefficient_table()
        if bands is not None:
            import pandas as pd

            extra_columns = bands.coefficient_table().drop(columns=["coefficient", "value"])
            coefficients = pd.concat([coefficients, extra_columns], axis=1)
        options.wrote(write_table(coefficients, out, "--out"), f"coefficient table, {len(coefficients)} rows")
    nested = nested_summary(table, results) if nested_cv else None
    model_map = None
    if model_kind is not None or model_coupling is not None:
        from droptower.compare.model_map import build_model_map

        from droptower.io.mapping import parse_channel_options

        model_map = build_model_map(results, fit, family=model_kind, template=template, coupling_file=model_coupling,
                                    on_note=lambda text: options.note(cli_text(text)), on_progress=options.progress,
                                    rig=rig_config, roles=parse_channel_options(channel_specs),
                                    sensor_radius_m=sensor_radius_m, conditions=conditions_table, table=table,
                                    uncertainty=input_u, **geometry)
    extra = {**({"nested_cross_validation": nested} if nested is not None else {}),
             **({"uncertainty": _uncertainty_json(bands)} if bands is not None else {}),
             **({"model_map": model_map.to_dict()} if model_map is not None else {})}
    if as_json and extra:
        click.echo(json.dumps({**json.loads(fit.to_json()), **extra}, indent=2))
    elif as_json:
        click.echo(fit.to_json(), nl=False)
    else:
        click.echo(fit.summary())
        if bands is not None:
            click.echo(_uncertainty_text(bands))
        if nested is not None:
            click.echo(f"nested cross-validated (terms chosen without each fold's tests, {nested['inner_folds']} "
                       f"inner folds): stiffness {nested['stiffness_rms_error_pct']:.2f} %, damping ratio "
                       f"{nested['damping_ratio_rms_error_pct']:.2f} % (rms); chosen: {nested['chosen']}")
    poor = model_map is not None and model_map.identification.get("verdict") == "poor fit"
    if model_map is not None:
        if not as_json:
            click.echo(model_map.summary())
            if bands is not None and model_map.has_bands and not model_map.input_sets:
                from droptower.compare.validate import inertia_u_rel

                click.echo(f"inputs on the model-based map: J's {100 * inertia_u_rel(input_u, table):.3g} % on K' "
                           "(added to its bands in the figures and in validate's E_n; the loss factor carries no J)")
        if poor and not accept_poor:
            model_out = None  # a map that cannot be trusted is written only when asked
        if model_out is not None and model_out.suffix.lower() == ".json":
            model_map.to_json(model_out)
            options.wrote(model_out, f"the {model_map.route}; validate --model-map reads it")
        elif model_out is not None:
            options.wrote(write_table(model_map.grid, model_out, "--model-out"), f"{model_map.route}, grid")
    if plot_dir is not None:
        from droptower.maps.plots import plot_all

        files, notes = plot_all(select_tests(table, results)[0], fit, plot_dir, bands)
        for line in notes:
            options.note(f"note: {line}")
        if model_map is not None and (accept_poor or not poor):
            from droptower.compare.model_map_plots import plot_model_map

            drawn = model_map
            if bands is not None:  # the fit's bands and J's share on K' together
                from droptower.compare.validate import inertia_u_rel, model_map_with_inputs

                drawn = model_map_with_inputs(model_map, inertia_u_rel(input_u, table))
            files += plot_model_map(drawn, plot_dir, select_tests(table, results)[0], fit)
        options.wrote(plot_dir, f"{', '.join(p.name for p in files)}")
    if poor and not accept_poor:
        from droptower.identify.verdict import EXIT_POOR_FIT

        click.echo(f"droptower: family {model_kind}: poor fit to the drop tests; the {model_map.route} was not written "
                   f"(--accept-poor writes it; exit code {EXIT_POOR_FIT})", err=True)
        raise click.exceptions.Exit(EXIT_POOR_FIT)
    if failed:
        click.echo(f"droptower: {failed} log(s) could not be evaluated (listed above); exit code 2", err=True)
        raise click.exceptions.Exit(2)


def _uncertainty_json(bands: Any) -> dict[str, Any]:
    """The map's expanded uncertainties for ``--json``: per coefficient and the inputs not given."""
    from droptower.jsonsafe import json_safe

    return json_safe({"coverage_factor": 2.0, "not_given": list(bands.not_given),
                      "coefficients": bands.coefficient_table().to_dict(orient="records")})


def _uncertainty_text(bands: Any) -> str:
    """The summary's lines: each coefficient's U95 (k = 2), the fit's and the inputs' u, the dominant."""
    table = bands.coefficient_table()
    lines = ["expanded uncertainties (k = 2; the inputs correlated across the tests that share them):"]
    for row in table.itertuples():
        lines.append(f"  {row.coefficient:>4} = {row.value:.5g} ± {row.U95:.3g}  (u_fit {row.u_fit:.3g}, "
                     f"u_inputs {row.u_inputs:.3g}; largest: {row.dominant})")
    if bands.not_given:
        lines.append(f"  inputs not given: {', '.join(bands.not_given)}")
    return "\n".join(lines)


def _read_source(results: Path, rig: str | None, sensor_radius_m: float | None, channel_specs: tuple[str, ...],
                 conditions: str | None, condition_columns: tuple[str, ...], conditions_pattern: str | None,
                 reads_logs: bool = False, geometry: dict | None = None):
    """(results table, rig, conditions) of RESULTS: a lab's folder of logs is extracted first
    (every log, failed ones kept with their error); a conditions table's rows that name no log
    are warned of (nothing is dropped silently). The flags that read logs are refused where no
    log is read (a results table without --family): a flag is never ignored silently."""
    from droptower.errors import check_positive
    from droptower.io.mapping import parse_channel_options
    from droptower.maps import read_results
    from droptower.maps.fromlogs import is_log_folder, log_files, results_from_logs

    geometry = geometry or {}
    check_positive(sensor_radius_m, "--sensor-radius-m")
    check_positive(geometry.get("inertia_kgm2"), "--inertia-kgm2")
    check_positive(geometry.get("lever_length_m"), "--lever-length-m")
    folder = is_log_folder(results)
    log_flags = [flag for flag, given in (("--conditions", conditions), ("--conditions-from-names", conditions_pattern),
                                          ("--channel", channel_specs), ("--sensor-radius-m", sensor_radius_m),
                                          ("--inertia-kgm2", geometry.get("inertia_kgm2")),
                                          ("--lever-length-m", geometry.get("lever_length_m"))) if given]
    if log_flags and not folder and not reads_logs:
        raise DroptowerError(f"{', '.join(log_flags)} read logs: RESULTS is a results table, whose values are used as "
                             "they are (give a folder of logs, or --family to read the logs the table names)")
    logs = log_files(results, exclude=[p for p in (conditions, rig) if p]) if folder else []
    rig_config = options.rig_for_logs(rig, [str(p) for p in logs])
    conditions_table = options.conditions_from_cli(conditions, condition_columns, conditions_pattern, rig_config)
    if not folder:
        if results.is_dir() and not (results / "results.parquet").is_file() and not any(results.iterdir()):
            raise DroptowerError("an empty folder: give a results table, a campaign folder or a folder of logs",
                                 file=results)
        return read_results(results), rig_config, conditions_table
    options.progress(f"map: extracting {len(logs)} log(s) of {results} ...")
    table = results_from_logs(logs, rig=rig_config, roles=parse_channel_options(channel_specs),
                              sensor_radius_m=sensor_radius_m, conditions=conditions_table, **geometry)
    # named as in the folder (the summary lists them), not by the machine's paths
    table["file"] = [Path(str(f)).relative_to(results).as_posix() if Path(str(f)).is_relative_to(results) else f
                     for f in table["file"]]
    if conditions_table is not None:
        for name in conditions_table.unmatched(logs):
            click.echo(f"droptower: warning: {conditions_table.source}: row '{name}' names no log of {results}", err=True)
    return table, rig_config, conditions_table


def failed_logs(table) -> int:
    """Print each log of a folder whose extraction failed, one error line naming it (at once,
    before the map: a map that cannot be fitted still names them); returns how many. Every log
    failing for one reason (the geometry or the conditions not given) is one error, not a line
    per log."""
    if "status" not in table.columns:
        return 0
    rows = table[table["status"].astype(str) == "failed"]
    reasons = set(rows["error"].astype(str)) if "error" in rows.columns else set()
    if len(rows) == len(table) and len(rows) > 1 and len(reasons) == 1:
        raise DroptowerError(f"none of the {len(rows)} logs can be evaluated: {reasons.pop()}")
    for _, row in rows.iterrows():
        click.echo(f"droptower: error: {row['file']}: {cli_text(str(row.get('error', 'failed')))}", err=True)
    return len(rows)
