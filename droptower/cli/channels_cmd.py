"""``droptower channels FILE [--json]``: what a log file holds, to write the channel mapping."""
from __future__ import annotations

import json
import math
from typing import Any

import click

from droptower.cli.options import quiet_option
import numpy as np

from droptower.io.channels import Channel
from droptower.io.readers import read_any


def describe(channel: Channel) -> dict[str, Any]:
    """One channel as a row: name, unit, samples, sample rate or time base, first/last value,
    catman invalid markers and NaN counts. Keys carry their units."""
    values = channel.values
    invalid = int(channel.invalid.sum()) if channel.invalid is not None else 0
    time = channel.time()
    rate = channel.sample_rate_hz
    if rate is None and time is not None and time.size > 1 and time[-1] != time[0]:
        step = np.diff(time)
        if np.allclose(step, step.mean(), rtol=1e-6, atol=0):
            rate = (time.size - 1) / (time[-1] - time[0])

    def number(x: float | None) -> float | None:
        return None if x is None or not math.isfinite(x) else float(x)

    return {
        "name": channel.name,
        "unit": channel.unit,
        "samples": int(values.size),
        "sample_rate_hz": number(rate),
        "first_time_s": number(time[0]) if time is not None and time.size else None,
        "last_time_s": number(time[-1]) if time is not None and time.size else None,
        "first_value": number(values[0]) if values.size else None,
        "last_value": number(values[-1]) if values.size else None,
        "invalid_markers": invalid,
        "nan": int(np.isnan(values).sum()) - invalid,
    }


def _cell(value: Any) -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        return f"{value:.6g}"
    return str(value)


@click.command()
@quiet_option
@click.argument("file", type=click.Path(dir_okay=False, path_type=str))
@click.option("--json", "as_json", is_flag=True, help="Print a JSON list of channel objects instead of a table.")
@click.option("--delimiter", default=None, help="CSV field separator (default: sniffed).")
@click.option("--decimal", type=click.Choice([".", ","]), default=None, help="CSV decimal separator (default: sniffed).")
@click.option("--header-lines", type=int, default=None, help="CSV lines above the names row (default: sniffed).")
@click.option("--unit-row/--no-unit-row", default=None, help="CSV has a units row under the names (default: sniffed).")
def channels(file: str, as_json: bool, delimiter: str | None, decimal: str | None, header_lines: int | None,
             unit_row: bool | None) -> None:
    """List the channels of a log FILE: name, unit, samples, sample rate or time base, first and
    last value, catman invalid markers (-1000000) and NaN counts.

    Use the names with --channel ROLE=NAME[:UNIT] (roles: time, impact_force, angle, distance,
    torque). Formats: droptower logs (.csv/.parquet), CSV/ASCII (catman ASCII, MTS 793 .dat),
    HBM catman .BIN, MDF4, TDMS, Parquet.

    \b
    Examples:
      droptower channels drop_017.bin
      droptower channels export.csv --delimiter ";" --decimal , --json
    """
    if delimiter == "\\t":
        delimiter = "\t"
    record = read_any(file, delimiter=delimiter, decimal=decimal, header_lines=header_lines, unit_row=unit_row)
    rows = [describe(channel) for channel in record.channels.values()]
    if as_json:
        click.echo(json.dumps(rows, indent=2))
        return
    header = ["name", "unit", "samples", "rate_hz", "first_time_s", "last_time_s", "first_value", "last_value",
              "invalid", "nan"]
    table = [[_cell(v) for v in row.values()] for row in rows]
    widths = [max(len(h), *(len(r[i]) for r in table)) for i, h in enumerate(header)]
    click.echo(f"{record.path} ({record.format}, {len(rows)} channels)")
    for line in [header, *table]:
        click.echo("  ".join(cell.ljust(w) if i < 2 else cell.rjust(w) for i, (cell, w) in enumerate(zip(line, widths))).rstrip())
