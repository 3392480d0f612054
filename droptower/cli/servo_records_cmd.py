"""``droptower evaluate-servo``: raw servo time records -> the bench's K', K'', loss factor per block.

A thin layer over :func:`droptower.servo.evaluate_records`; the table it writes is what
``droptower validate --servo-results`` reads, and ``validate --servo-records`` runs the same
evaluation in one go (:func:`servo_record_options`, :func:`evaluate_for_validate`).
"""
from __future__ import annotations

import contextlib
import json
import math
import re
import tempfile
from pathlib import Path
from typing import Any, Callable, Iterator

import click

from droptower.cli.options import note, quiet_option, wrote
from droptower.errors import DroptowerError

#: Columns of the printed table (every column is in --out and --json).
TABLE_COLUMNS = ["file", "block", "amplitude_deg", "frequency_hz", "storage_stiffness_nm_per_deg",
                 "storage_stiffness_std_nm_per_deg", "loss_stiffness_nm_per_deg", "loss_factor", "loss_factor_std",
                 "evaluated_cycles", "block_cycles"]


def _evaluate(records: tuple[str, ...], channels: tuple[str, ...], sample_rate_hz: float | None,
              sample_interval_s: float | None, lever_arm_m: float | None, cycles: int, settle_cycles: int,
              smooth: bool) -> tuple[Any, list[DroptowerError]]:
    """The table of the records that could be evaluated and the failures (notes printed)."""
    from droptower.io.mapping import SERVO_ROLES, parse_channel_options
    from droptower.servo.records import evaluate_records

    notes: list[str] = []
    failures: list[DroptowerError] = []
    table = evaluate_records(records, parse_channel_options(channels, SERVO_ROLES), sample_rate_hz=sample_rate_hz,
                             sample_interval_s=sample_interval_s, lever_arm_m=lever_arm_m, cycles=cycles,
                             settle_cycles=settle_cycles, smooth=smooth, notes=notes, failures=failures)
    for text in notes:
        note(f"note: {text}")
    return table, failures


def _steadiness_warnings(table: Any) -> None:
    from droptower.cli.servo_cmd import STEADY_WARNING

    for _, row in table.iterrows():
        if row["steady_state_deviation"] > STEADY_WARNING:
            click.echo(f"droptower: warning: {row['file']}, block {row['block']} ({row['frequency_hz']:.4g} Hz): "
                       f"single cycles differ by {100 * row['steady_state_deviation']:.1f} % (not steady: raise "
                       "--settle-cycles, or the record is noisy)", err=True)


@click.command("evaluate-servo")
@quiet_option
@click.argument("records", nargs=-1, required=True, type=click.Path(readable=False))
@click.option("--channel", "channels", multiple=True, metavar="ROLE=NAME[:UNIT]",
              help="Name a channel and its unit (roles time, angle, torque, displacement, force); repeatable. "
                   "Channels named like time, angle, torque, displacement, force (Zeit, Winkel, Moment, Weg, "
                   "Kraft, ...) are found without it.")
@click.option("--sample-rate-hz", type=float, default=None,
              help="Records without a time channel: their sample rate (Hz).")
@click.option("--sample-interval-s", type=float, default=None,
              help="Records without a time channel: their sample interval (s); instead of --sample-rate-hz.")
@click.option("--lever-arm-m", type=float, default=None,
              help="Translational records (displacement, force): read them as a lever of this radius (m) driven "
                   "along its arc (angle = x / r, torque = F r), torsional results for `validate`.")
@click.option("--cycles", default=5, show_default=True, type=click.IntRange(min=1),
              help="Cycles evaluated per block: the last ones (fewer if the block is shorter).")
@click.option("--settle-cycles", default=1, show_default=True, type=click.IntRange(min=0),
              help="Cycles at the start of every block never evaluated (the run-in after an amplitude change).")
@click.option("--no-smoothing", is_flag=True,
              help="Skip the one-eighth-cycle Savitzky-Golay smoothing of the lab's evaluation.")
@click.option("--out", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Write the table (.csv, .parquet, .json, .xlsx): what `validate --servo-results` reads.")
@click.option("--json", "as_json", is_flag=True, help="Print a JSON list of objects (one per block) instead of a table.")
@click.option("--uncertainty", "uncertainty_specs", multiple=True, metavar="INPUT=VALUE",
              help="The bench's own uncertainty: a channel's calibration as a relative standard uncertainty, "
                   "torque_calibration_rel=0.005 or angle_calibration_rel=0.003 (repeatable). With it (or "
                   "without VALUE pairs: --uncertainty scatter) each block gains its U95 (k = 2) from the "
                   "cycles' scatter and the calibrations, in the columns validate --servo-results reads.")
def evaluate_servo(records: tuple[str, ...], channels: tuple[str, ...], sample_rate_hz: float | None,
                   sample_interval_s: float | None, lever_arm_m: float | None, cycles: int, settle_cycles: int,
                   no_smoothing: bool, out: Path | None, as_json: bool, uncertainty_specs: tuple[str, ...] = ()) -> None:
    """Evaluate raw servo-hydraulic time RECORDS as a lab's bench software does: per
    amplitude/frequency block (found from the imposed motion: plateaus of amplitude, also when
    the blocks ramp up from rest), the first --settle-cycles cycles skipped and the last --cycles
    cycles evaluated through the virtual bench's own evaluation: first-harmonic K' and K''
    (the elastoslide paper, eq. 6), loss factor, loop work, psi, the drop-tower-equivalent
    damping ratio, each with its scatter (standard deviation) over the evaluated cycles.

    RECORDS: one file per test or one file with several blocks, in any format the readers
    take (CSV in any dialect, Parquet, TDMS, MDF, catman): time (or --sample-rate-hz /
    --sample-interval-s), angle and torque, or displacement and force (a translational
    record: fields named for it, or torsional through --lever-arm-m). A record that cannot be
    evaluated is one line; the others go on and the failures are listed at the end (exit 2).

    \b
    Examples:
      droptower evaluate-servo sweep_*.csv --out bench.csv
      droptower validate --map map.json --servo-results bench.csv
      droptower evaluate-servo test.txt --sample-interval-s 0.01 --channel displacement=d:cm --channel force=f:kN
      droptower evaluate-servo bearing.csv --lever-arm-m 0.25 --out bench.xlsx
    """
    import pandas as pd

    from droptower.cli.flags import cli_message
    from droptower.io.fields import field_name
    from droptower.io.tables import check_table_path, write_table
    from droptower.jsonsafe import json_safe

    if out is not None:
        check_table_path(out, "--out")  # a bad --out fails before the evaluation
    calibrations = _calibrations(uncertainty_specs)
    table, failures = _evaluate(records, channels, sample_rate_hz, sample_interval_s, lever_arm_m, cycles,
                                settle_cycles, not no_smoothing)
    if uncertainty_specs and len(table):
        from droptower.uncertainty.bench import bench_u95

        table = bench_u95(table, **calibrations)
    if failures and len(records) == 1:
        raise failures[0]  # one file, one failure: its line says it all
    for exc in failures:
        click.echo(f"droptower: error: {cli_message(exc)}", err=True)
    if len(table):
        units = "translational" if "storage_stiffness_n_per_m" in table.columns else "torsional"
        _steadiness_warnings(table.rename(columns={field_name("amplitude_deg", units): "amplitude_deg"}))
        if out is not None:
            wrote(write_table(table, out, "--out"), f"{len(table)} block(s) of {table['file'].nunique()} record(s)")
        if as_json:
            click.echo(json.dumps(json_safe(table.to_dict(orient="records")), indent=1))
        elif out is None:
            columns = [field_name(c, units) for c in TABLE_COLUMNS]
            columns += [c for c in table.columns if c.endswith("_U95") and c not in columns]
            with pd.option_context("display.width", 250, "display.max_columns", None):
                click.echo(table[columns].to_string(index=False, float_format=lambda v: f"{v:.5g}"))
    if failures:
        click.echo(f"droptower: {len(failures)} of {len(records)} record(s) failed:", err=True)
        for exc in failures:
            click.echo(f"  {cli_message(exc)}", err=True)
        raise click.exceptions.Exit(2)


def _calibrations(specs: tuple[str, ...]) -> dict[str, float]:
    """``--uncertainty`` of evaluate-servo: INPUT=VALUE pairs (or ``scatter``: the cycles' alone)."""
    names = ("torque_calibration_rel", "angle_calibration_rel")
    out: dict[str, float] = {}
    for spec in specs:
        if spec.strip() == "scatter":
            continue
        name, sep, value = spec.partition("=")
        try:
            number = float(value)
        except ValueError:
            number = math.nan
        if not sep or name.strip() not in names or not (math.isfinite(number) and 0 <= number < 1):
            raise DroptowerError(f"--uncertainty {spec!r}: give {names[0]}=REL or {names[1]}=REL (a relative standard "
                                 "uncertainty in [0, 1), e.g. 0.005), or scatter")
        out[name.strip()] = number
    return out


# ---- validate --servo-records: the same evaluation in one go --------------------------------------------------

#: Python parameter -> the flag `validate` gives it by (its own flags carry a servo- prefix)
VALIDATE_FLAGS = {"sample_rate_hz": "--servo-sample-rate-hz", "sample_interval_s": "--servo-sample-interval-s",
                  "lever_arm_m": "--servo-lever-arm-m", "cycles": "--servo-cycles",
                  "settle_cycles": "--servo-settle-cycles"}


def servo_record_options(command: Callable) -> Callable:
    """The options of ``validate`` that evaluate raw servo records in one go."""
    for option in reversed([
        click.option("--servo-records", "servo_records", multiple=True, type=click.Path(readable=False),
                     metavar="FILE", help="Raw servo time records (repeatable) evaluated as `droptower evaluate-servo` "
                                          "does, instead of --servo-results."),
        click.option("--servo-channel", "servo_channels", multiple=True, metavar="ROLE=NAME[:UNIT]",
                     help="With --servo-records: name a channel (roles time, angle, torque, displacement, force)."),
        click.option("--servo-sample-rate-hz", type=float, default=None,
                     help="With --servo-records: the sample rate of records without a time channel (Hz)."),
        click.option("--servo-sample-interval-s", type=float, default=None,
                     help="With --servo-records: the sample interval of records without a time channel (s)."),
        click.option("--servo-lever-arm-m", type=float, default=None,
                     help="With --servo-records: read translational records as a lever of this radius (m)."),
    ]):
        command = option(command)
    return command


def _validate_text(text: str) -> str:
    text = re.sub(r"`roles=\{'(\w+)': '([^']*)'\}`", lambda m: f"--servo-channel {m.group(1)}={m.group(2)}", text)
    return re.sub(r"`(\w+)`", lambda m: VALIDATE_FLAGS.get(m.group(1), m.group(0)), text)


def evaluate_for_validate(records: tuple[str, ...], channels: tuple[str, ...], sample_rate_hz: float | None,
                          sample_interval_s: float | None, lever_arm_m: float | None, folder: Path) -> Path:
    """Evaluate ``records`` (``validate --servo-records``) and write the table into ``folder`` as
    ``servo_records.csv``; returns its path. Any record that cannot be evaluated stops the
    validation (every failure is printed, one line each): no record is silently left out."""
    try:
        table, failures = _evaluate(records, channels, sample_rate_hz, sample_interval_s, lever_arm_m, 5, 1, True)
    except DroptowerError as exc:
        raise DroptowerError(_validate_text(exc.problem), file=exc.file, where=exc.where) from None
    failures = [DroptowerError(_validate_text(f.problem), file=f.file, where=f.where) for f in failures]
    if len(failures) == 1:
        raise failures[0]
    if failures:
        for exc in failures:
            click.echo(f"droptower: error: {exc.message}", err=True)
        raise DroptowerError(f"{len(failures)} of {len(records)} servo record(s) could not be evaluated (above)")
    if "storage_stiffness_nm_per_deg" not in table.columns:
        raise DroptowerError("the servo records are translational (displacement, force): the map is the torsional "
                             "drop tower's; give --servo-lever-arm-m to read them as a lever's angle and torque")
    from droptower.io.tables import write_table

    return write_table(table, folder / "servo_records.csv", "--out")

@contextlib.contextmanager
def servo_records_table(options: dict[str, Any], servo_results: Path | None, out: Path | None) -> Iterator[Path | None]:
    """``validate``'s servo results: ``servo_results`` as given, or with ``--servo-records`` the
    records evaluated into ``out/servo_records.csv`` (kept and announced) or, without ``--out``, a
    temporary table that lives while the block runs."""
    records = tuple(options.get("servo_records") or ())
    given = [flag for key, flag in (("servo_channels", "--servo-channel"), ("servo_sample_rate_hz", "--servo-sample-rate-hz"),
                                    ("servo_sample_interval_s", "--servo-sample-interval-s"),
                                    ("servo_lever_arm_m", "--servo-lever-arm-m")) if options.get(key)]
    if not records:
        if given:
            raise DroptowerError(f"{', '.join(given)} need{'s' if len(given) == 1 else ''} --servo-records "
                                 "(the raw records they describe)")
        yield servo_results
        return
    if servo_results is not None:
        raise DroptowerError("give --servo-results (evaluated results) or --servo-records (raw records), not both")
    args = (records, tuple(options.get("servo_channels") or ()), options.get("servo_sample_rate_hz"),
            options.get("servo_sample_interval_s"), options.get("servo_lever_arm_m"))
    if out is not None:
        path = evaluate_for_validate(*args, out)
        wrote(path, "the servo records evaluated, one row per block")
        yield path
        return
    with tempfile.TemporaryDirectory(prefix="droptower-servo-records-") as folder:
        yield evaluate_for_validate(*args, Path(folder))


def name_servo_source(result: Any, options: dict[str, Any]) -> None:
    """With ``--servo-records``: the validation's servo source names the records (the table they
    were evaluated into may be a temporary one), not the table's path."""
    records = tuple(options.get("servo_records") or ())
    if records:
        names = ", ".join(Path(r).name for r in records[:3]) + (f" and {len(records) - 3} more" if len(records) > 3 else "")
        result.validation.summary["servo_source"] = (f"servo records {names}, evaluated as `droptower evaluate-servo` "
                                                     "does (the last 5 cycles of every block after 1 settling cycle)")
