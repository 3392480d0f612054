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
def report(source: Path, out: Path | None, form: str, channel_specs: tuple[str, ...]) -> None:
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

    path = write_report(source, out, form=form, channels=parse_channel_options(channel_specs), progress=options.progress_disabled() is None)
    options.wrote(path, f"HTML report, {path.stat().st_size / 1e6:.1f} MB")
