"""``droptower map``: fit the characteristic map (seed 004 eq. 19 and eq. 20) to a results table."""
from __future__ import annotations

from pathlib import Path

import click

from droptower.cli import options
from droptower.cli.options import quiet_option


@click.command("map")
@quiet_option
@click.argument("results", type=click.Path(path_type=Path))
@click.option("--out", type=click.Path(path_type=Path, dir_okay=False), default=None,
              help="Write the map: map.json (coefficients, uncertainties, errors, range; what validate --map "
                   "reads) or the coefficient table as .csv, .parquet or .xlsx.")
@click.option("--plot", "plot_dir", type=click.Path(path_type=Path, file_okay=False), default=None,
              help="Write the paper's Fig. 10, 12 and 13 as PNG files into this folder.")
@click.option("--form", type=click.Choice(["paper", "velocity", "auto"]), default="paper", show_default=True,
              help="paper: seed 004 eq. 19/20; velocity: stiffness and c/d also fall with amplitude x frequency; "
                   "auto: the terms with the least cross-validated error whose coefficients are all identifiable.")
@click.option("--json", "as_json", is_flag=True, help="Print the map as JSON instead of the summary.")
def map_command(results: Path, out: Path | None, plot_dir: Path | None, form: str, as_json: bool) -> None:
    """Fit stiffness c(amplitude, frequency) (eq. 19) and damping c/d(amplitude) (eq. 20),
    or another --form; the summary gives fit and cross-validated errors.

    RESULTS is a CSV or Parquet table from `droptower extract --out`, a `droptower campaign`
    folder (its results.parquet), or the paper's Table 4. Flagged tests (double_impact, poor_fit, short_window, clipping)
    and incomplete rows are excluded and listed.

    \b
    Examples:
      droptower map runs/table2 --out map.json --plot figs/
      droptower map results.csv --out coefficients.xlsx
    """
    from droptower.io.tables import check_table_path, write_table
    from droptower.maps import fit_map, read_results, select_tests

    if out is not None:
        check_table_path(out, "--out")
    table = read_results(results)
    fit = fit_map(table, source=results, form=form)
    if out is not None and out.suffix.lower() == ".json":
        fit.to_json(out)
        options.wrote(out, f"the map: {len(fit.form.units)} coefficients, errors, range; validate --map reads it")
    elif out is not None:
        coefficients = fit.coefficient_table()
        options.wrote(write_table(coefficients, out, "--out"), f"coefficient table, {len(coefficients)} rows")
    click.echo(fit.to_json() if as_json else fit.summary(), nl=not as_json)
    if plot_dir is not None:
        from droptower.maps.plots import plot_all

        files, notes = plot_all(select_tests(table, results)[0], fit, plot_dir)
        for line in notes:
            options.note(f"note: {line}")
        options.wrote(plot_dir, f"{', '.join(p.name for p in files)}")
