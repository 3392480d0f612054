"""``droptower map``: fit the characteristic map (Rapp et al. 2022, eq. 19 and eq. 20) to a results table."""
from __future__ import annotations

import json
from pathlib import Path

import click

from droptower.cli import options
from droptower.cli.options import quiet_option
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
def map_command(results: Path, out: Path | None, plot_dir: Path | None, form: str, nested_cv: bool,
                as_json: bool) -> None:
    """Fit stiffness c(amplitude, frequency) (eq. 19) and damping c/d(amplitude) (eq. 20),
    or another --form; the summary gives fit and cross-validated errors.

    RESULTS is a CSV or Parquet table from `droptower extract --out`, a `droptower campaign`
    folder (its results.parquet), or the paper's Table 4. Flagged tests (double_impact, poor_fit, short_window, clipping)
    and incomplete rows are excluded and listed.

    \b
    Examples:
      droptower map runs/table2 --out map.json --plot figs/
      droptower map results.csv --out coefficients.xlsx
      droptower map rapp2022_table4 --form auto --nested-cv
    """
    from droptower.io.tables import check_table_path, write_table
    from droptower.maps import fit_map, read_results, select_tests

    if out is not None:
        check_table_path(out, "--out")
    if nested_cv and form != "auto":
        raise DroptowerError("--nested-cv cross-validates auto's choice of terms: use it with --form auto")
    table = read_results(results)
    fit = fit_map(table, source=results, form=form)
    if out is not None and out.suffix.lower() == ".json":
        fit.to_json(out)
        options.wrote(out, f"the map: {len(fit.form.units)} coefficients, errors, range; validate --map reads it")
    elif out is not None:
        coefficients = fit.coefficient_table()
        options.wrote(write_table(coefficients, out, "--out"), f"coefficient table, {len(coefficients)} rows")
    nested = _nested(table, results) if nested_cv else None
    if as_json and nested is not None:
        click.echo(json.dumps({**json.loads(fit.to_json()), "nested_cross_validation": nested}, indent=2))
    elif as_json:
        click.echo(fit.to_json(), nl=False)
    else:
        click.echo(fit.summary())
        if nested is not None:
            click.echo(f"nested cross-validated (terms chosen without each fold's tests, {nested['inner_folds']} "
                       f"inner folds): stiffness {nested['stiffness_rms_error_pct']:.2f} %, damping ratio "
                       f"{nested['damping_ratio_rms_error_pct']:.2f} % (rms); chosen: {nested['chosen']}")
    if plot_dir is not None:
        from droptower.maps.plots import plot_all

        files, notes = plot_all(select_tests(table, results)[0], fit, plot_dir)
        for line in notes:
            options.note(f"note: {line}")
        options.wrote(plot_dir, f"{', '.join(p.name for p in files)}")


def _nested(table, source: Path) -> dict:
    """The nested cross-validation of auto on the usable tests, as plain data (units in the keys)."""
    from droptower.maps import select_tests
    from droptower.maps.results import REQUIRED
    from droptower.maps.nested import INNER_FOLDS, chosen_summary, nested_cv
    from droptower.maps.select import cv_groups

    usable = select_tests(table, source)[0]
    a, f, c, d = (usable[col].to_numpy(float) for col in REQUIRED)
    groups, method = cv_groups(usable)
    result = nested_cv(a, f, c, d, groups)
    return {"outer": method, "inner_folds": INNER_FOLDS, "stiffness_rms_error_pct": result.stiffness_rms_pct,
            "damping_ratio_rms_error_pct": result.damping_ratio_rms_pct, "chosen": chosen_summary(result)}
