"""``droptower channels FILE [--json]``: what a log file holds, to write the channel mapping."""
from __future__ import annotations

import json
import math
from typing import Any

import click

from droptower.cli.options import quiet_option
import numpy as np

from droptower.errors import DroptowerError
from droptower.io.channels import Channel, Record
from droptower.io.droptower_log import unit_from_name
from droptower.io.mapping import KINDS, ROLES, SERVO_KINDS, SERVO_ROLES, check_units, find_roles, find_servo_roles, parse_channel_options
from droptower.io.readers import read_any
from droptower.io.timebase import regular_time
from droptower.units import to_si
from droptower.cli.flags import cli_text


def describe(channel: Channel, role: str | None = None, base_s: np.ndarray | None = None,
             servo_role: str | None = None) -> dict[str, Any]:
    """One channel as a row: name, unit (as written, else from a name suffix such as
    ``torque_nm``), samples, sample rate and time span (its own time base, else ``base_s``, the
    file's time channel in s, when the lengths agree; time stamps rounded to their printed
    precision give the constant rate behind them), first/last value, catman invalid markers,
    NaN counts, the role ``extract`` would give it and the one ``identify`` would (a servo
    record: angle/torque or displacement/force). Keys carry their units."""
    values = channel.values
    invalid = int(channel.invalid.sum()) if channel.invalid is not None else 0
    time = channel.time()
    if time is None and base_s is not None and base_s.size == values.size:
        time = base_s
    rate = channel.sample_rate_hz
    if rate is None and time is not None and time.size > 1 and np.all(np.diff(time) > 0):
        try:
            uniform, _ = regular_time(time)
            rate = (uniform.size - 1) / (uniform[-1] - uniform[0])
        except DroptowerError:
            rate = None  # truly irregular: no one rate

    def number(x: float | None) -> float | None:
        return None if x is None or not math.isfinite(x) else float(x)

    return {
        "name": channel.name,
        "unit": channel.unit or unit_from_name(channel.name),
        "samples": int(values.size),
        "sample_rate_hz": number(rate),
        "first_time_s": number(time[0]) if time is not None and time.size else None,
        "last_time_s": number(time[-1]) if time is not None and time.size else None,
        "first_value": number(values[0]) if values.size else None,
        "last_value": number(values[-1]) if values.size else None,
        "invalid_markers": invalid,
        "nan": int(np.isnan(values).sum()) - invalid,
        "role": role,
        "servo_role": servo_role,
    }


def time_base(record: Record, roles: dict[str, str]) -> tuple[np.ndarray | None, str]:
    """The file's time channel in s (None if there is none or it cannot be read) and, in words,
    where the time of the samples comes from."""
    if "time" in roles:
        name, _, unit = roles["time"].partition(":") if roles["time"] not in record.channels else (roles["time"], "", "")
        channel = record.channels.get(name)
        if channel is not None:
            unit = unit or channel.unit or unit_from_name(name)
            try:
                return to_si(channel.values, unit, "time", file=record.path, channel=name), f"channel '{name}'"
            except DroptowerError as exc:
                return None, f"channel '{name}', unreadable ({cli_text(exc.problem)})"
    if any(c.time() is not None for c in record.channels.values()):
        return None, "each channel's own sample rate"
    return None, "none (give --sample-rate-hz to extract)"


def _cell(value: Any) -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        return f"{value:.6g}"
    return str(value)


@click.command()
@quiet_option
@click.argument("file", type=click.Path(path_type=str))
@click.option("--channel", "channel_specs", multiple=True, metavar="ROLE=NAME[:UNIT]",
              help="Try a channel mapping (as extract takes it): the roles column shows the result.")
@click.option("--json", "as_json", is_flag=True, help="Print a JSON list of channel objects instead of a table.")
@click.option("--delimiter", default=None, help="CSV field separator (default: sniffed).")
@click.option("--decimal", type=click.Choice([".", ","]), default=None, help="CSV decimal separator (default: sniffed).")
@click.option("--header-lines", type=int, default=None, help="CSV lines above the names row (default: sniffed).")
@click.option("--unit-row/--no-unit-row", default=None, help="CSV has a units row under the names (default: sniffed).")
def channels(file: str, channel_specs: tuple[str, ...], as_json: bool, delimiter: str | None, decimal: str | None, header_lines: int | None,
             unit_row: bool | None) -> None:
    """List the channels of a log FILE: name, unit (as written, else from a name suffix such as
    angle_deg), samples, sample rate and time span (for CSV: from the time channel), first and
    last value, catman invalid markers (-1000000), NaN counts, and the role each channel would
    get in `droptower extract` (found by name, or as --channel gives it), and the drops extract
    would find (a continuous recording holds several) with their impact times.

    Use the names with --channel ROLE=NAME[:UNIT] (roles: time, impact_force, angle, distance,
    torque). The servo_role column is the role `identify` and `compare-models` would give it
    (time, angle, torque; or displacement, force for a translational record of a mount, bushing
    or damper in any length and force units: m, mm, µm, in; N, kN, lbf, kip). Formats: droptower logs (.csv/.parquet), CSV/ASCII (catman ASCII, MTS 793 .dat),
    HBM catman .BIN, MDF4, TDMS, Parquet.

    \b
    Examples:
      droptower channels drop_017.bin
      droptower channels export.csv --delimiter ";" --decimal , --json
    """
    if delimiter == "\\t":
        delimiter = "\t"
    record = read_any(file, delimiter=delimiter, decimal=decimal, header_lines=header_lines, unit_row=unit_row)
    problems: list[str] = []
    given = parse_channel_options(channel_specs, tuple(dict.fromkeys(ROLES + SERVO_ROLES)))
    check_units(record, {role: spec for role, spec in given.items() if role in KINDS})
    roles = find_roles(record, {r: v for r, v in given.items() if r in ROLES}, problems)
    servo_problems: list[str] = []
    servo_units, servo_roles = find_servo_roles(record, {r: v for r, v in given.items() if r in SERVO_ROLES},
                                                servo_problems)

    def channel_of(spec: str) -> str:
        return spec if spec in record.channels else spec.rpartition(":")[0]

    role_of = {channel_of(spec): role for role, spec in roles.items()}
    servo_role_of = {channel_of(spec): role for role, spec in servo_roles.items()}
    base_s, base_text = time_base(record, roles)
    rows = [describe(channel, role_of.get(name), base_s, servo_role_of.get(name))
            for name, channel in record.channels.items()]
    if as_json:
        click.echo(json.dumps(rows, indent=2))
        return
    header = ["name", "unit", "samples", "rate_hz", "first_time_s", "last_time_s", "first_value", "last_value",
              "invalid", "nan", "role", "servo_role"]
    table = [[_cell(v) for v in row.values()] for row in rows]
    widths = [max(len(h), *(len(r[i]) for r in table)) for i, h in enumerate(header)]
    left = {0, 1, len(header) - 2, len(header) - 1}
    click.echo(f"{record.path} ({record.format}, {len(rows)} channels; time base: {base_text})")
    for line in [header, *table]:
        click.echo("  ".join(cell.ljust(w) if i in left else cell.rjust(w)
                             for i, (cell, w) in enumerate(zip(line, widths))).rstrip())
    click.echo(_drops_line(record, roles))
    missing = [role for role in ROLES if role not in roles and not (role == "distance" and "angle" in roles)]
    if missing:
        click.echo(f"drop-test roles not found: {', '.join(missing)} (name them with --channel ROLE=NAME[:UNIT])")
    for problem in problems:
        click.echo(f"roles: {problem}")
    motion, load = SERVO_KINDS[servo_units]
    if motion in servo_roles:
        click.echo(f"servo record: {servo_units} ({motion} and {load}"
                   f"{'' if load in servo_roles else f'; no {load} channel found'})")
    for problem in servo_problems:
        click.echo(f"servo roles: {problem}")


def _drops_line(record: Record, roles: dict[str, str]) -> str:
    """The drops ``extract`` would find in the record (a continuous recording holds several)."""
    from droptower.extract.drop_spans import find_drops
    from droptower.io.mapping import map_channels

    try:
        # the drops are found on the angle's shape, which the laser radius only scales
        signals = map_channels(record, roles, sensor_radius_m=1.0)
        spans = find_drops(signals)
    except DroptowerError as exc:
        return f"drops: none located ({cli_text(exc.problem)})"
    times = ", ".join(f"{signals.time_s[s.onset]:.4g}" for s in spans[:20]) + (", ..." if len(spans) > 20 else "")
    cut = [str(s.index) for s in spans if s.cut]
    return f"drops: {len(spans)} (impacts at t = {times} s)" + (
        f"; cut by the next drop: {', '.join(cut)}" if cut else "")
