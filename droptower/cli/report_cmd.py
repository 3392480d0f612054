"""``droptower report``: one self-contained HTML report of a campaign folder or a results table."""
from __future__ import annotations

from pathlib import Path

import click

from droptower.cli import options


@click.command("report")
@options.quiet_option
@click.argument("source", type=click.Path(path_type=Path))
@click.option("--out", type=click.Path(path_type=Path, dir_okay=False), default=None,
              help="The HTML file to write (default: DIR/report.html, or the results table's name with .html).")
@click.option("--form", type=click.Choice(["paper", "velocity", "auto"]), default="paper", show_default=True,
              help="The map form (as droptower map --form).")
@click.option("--channel", "channel_specs", multiple=True, metavar="ROLE=NAME[:UNIT]",
              help="Channel mapping for reading real logs again (as droptower extract --channel).")
@click.option("--model-map", "model_map_path", type=click.Path(path_type=Path, dir_okay=False), default=None,
              help="Also show the model-based map (model_map.json from `droptower map --model-out`) beside the "
                   "paper's, both validated against the servo bench on the campaign's own coupling.")
def report(source: Path, out: Path | None, form: str, channel_specs: tuple[str, ...],
           model_map_path: Path | None) -> None:
    """Write one HTML report (opens offline, no server) of SOURCE: a `droptower campaign` folder,
    or a results table from `droptower extract --out` with its logs.

    Summary of the run, failures and flags with their reasons, the map with its coefficients and
    fit and cross-validated errors, a sortable table of the tests, and per test the measured angle
    and torque with the decay fit and its window (the logs are extracted again for the plots).

    \b
    Examples:
      droptower report runs/table2                      # -> runs/table2/report.html
      droptower report results.csv --out report.html --form auto
    """
    from droptower.io.mapping import parse_channel_options
    from droptower.report import write_report

    extra = [_routes(source, model_map_path, form)] if model_map_path is not None else None
    path = write_report(source, out, form=form, channels=parse_channel_options(channel_specs),
                        extra_sections=extra, progress=options.progress_disabled() is None)
    options.wrote(path, f"HTML report, {path.stat().st_size / 1e6:.1f} MB")


def _routes(source: Path, model_map_path: Path, form: str) -> tuple[str, str]:
    """The two-routes section; the servo sweeps run on a campaign folder's own coupling."""
    from droptower.campaign.folder import saved_inputs
    from droptower.compare.model_map import ModelMap
    from droptower.report.routes import routes_report_section

    coupling = saved_inputs(source).get("coupling") if source.is_dir() else None
    if coupling is None:
        options.note("note: no campaign coupling to run the servo sweeps on: the routes are shown, not validated")
    return routes_report_section(source, ModelMap.from_json(model_map_path), form, coupling)
