"""``droptower identify`` and ``droptower compare-models``: coupling models from servo records.

DATA are imposed-angle / measured-torque records, or imposed-displacement / measured-force
records of mounts, bushings and dampers (translational), in any format the readers take
(channels found by name or given with ``--channel ROLE=NAME[:UNIT]``, roles ``time``,
``angle``, ``torque``, ``displacement``, ``force``). ``--params INIT.toml`` holds up to three tables::

    [initial]                 # starting values, by parameter name (see the report)
    k1_nm_per_rad = 8000.0
    [bounds]                  # [lower, upper]
    tau2_s = [0.5, 100.0]
    [options]                 # family options, and max_nfev, skip_s
    tau_split_s = 0.1
"""
from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import click
from pydantic import Field

from droptower.cli.options import note, progress, quiet_option, renamed_option, uncertainty_option, wrote
from droptower.errors import DroptowerError, check_positive
from droptower.config_validation import StrictModel, validate
from droptower.fit_defaults import DEFAULT_BUDGET_S, DEFAULT_TOTAL_BUDGET_S, HOLDOUT_FRACTION
from droptower.cli.flags import cli_text


#: the model families (droptower.identify.families.FAMILIES, named here so --help needs no import)
FAMILY_NAMES = ("zerodim6", "zerodim20", "elastoslide", "pfeffer", "masing", "overlay", "filled_rubber")
#: the families compare-models --from-drop-tests fits by default (droptower.identify.dropfit.DROP_FAMILIES)
DROP_FAMILY_NAMES = ("elastoslide", "zerodim6", "masing", "pfeffer", "filled_rubber")


class InitFile(StrictModel):
    """Layout of ``--params INIT.toml``."""

    initial: dict[str, float] = Field(default_factory=dict)
    bounds: dict[str, tuple[float, float]] = Field(default_factory=dict)
    options: dict[str, Any] = Field(default_factory=dict)


def drop_options(command):
    """The drop-test options ``identify`` and ``compare-models`` share (with the per-file
    conditions of :func:`~droptower.cli.options.conditions_options`)."""
    from droptower.cli.options import conditions_options

    command = conditions_options(command)
    for option in reversed([
            click.option("--holdout-fraction", type=click.FloatRange(0.0, 0.9), default=HOLDOUT_FRACTION, show_default=True,
                         help="Drop tests: share of the tests held out and predicted."),
            click.option("--rig", help="Drop tests: rig TOML or preset (lever length, laser radius, conditioning; "
                                       "the inertia of a single fixture, else --conditions say each log's)."),
            click.option("--inertia-kgm2", type=float, help="Drop tests: lever inertia J, overrides the logs' metadata."),
            click.option("--lever-length-m", type=float,
                         help="Drop tests: lever length L, overrides the logs' metadata."),
            click.option("--sensor-radius-m", type=float,
                         help="Drop tests: laser spot radius in m for a distance channel, over the logs' and the rig's.")]):
        command = option(command)
    return command


def _read_init(path: str | None) -> InitFile:
    if path is None:
        return InitFile()
    from droptower.configs import read_toml

    return validate(InitFile, read_toml(path), path)


def record_time_options(command):
    """``--sample-rate-hz`` and ``--sample-interval-s``: the time base of servo records without a
    time channel (published large-strain tests: displacement and force only), as
    ``evaluate-servo`` takes them."""
    for option in reversed([
            click.option("--sample-rate-hz", type=float, default=None,
                         help="Records without a time channel: their sample rate (Hz)."),
            click.option("--sample-interval-s", type=float, default=None,
                         help="Records without a time channel: their sample interval (s); instead of "
                              "--sample-rate-hz.")]):
        command = option(command)
    return command


def _refuse_time_base_for_drops(sample_rate_hz: float | None, sample_interval_s: float | None) -> None:
    """The servo records' time base is no drop-test flag: given with --from-drop-tests it is refused, never ignored."""
    given = [flag for flag, value in (("--sample-rate-hz", sample_rate_hz), ("--sample-interval-s", sample_interval_s))
             if value is not None]
    if given:
        raise DroptowerError(f"{' and '.join(given)} give{'s' if len(given) == 1 else ''} the time base of servo "
                             "records without a time channel; drop-test logs take theirs from the logs or --rig")


def _read_data(paths: tuple[str, ...], channels: tuple[str, ...], skip_s: float,
               sample_rate_hz: float | None = None, sample_interval_s: float | None = None):
    from droptower.identify.data import segments_from_files
    from droptower.io.mapping import SERVO_ROLES, parse_channel_options

    notes: list[str] = []
    segments = segments_from_files(paths, parse_channel_options(channels, SERVO_ROLES), skip_s=skip_s, notes=notes,
                                   sample_rate_hz=sample_rate_hz, sample_interval_s=sample_interval_s)
    for text in notes:
        note(f"note: {text}")
    return segments


@click.command()
@quiet_option
@click.argument("data", nargs=-1, required=True, type=click.Path(readable=False))
@renamed_option("--family", "--model", "kind", required=True, announce=True, type=click.Choice(FAMILY_NAMES + ("template",)),
                help="Model family (required).")
@click.option("--channel", "channels", multiple=True, metavar="ROLE=NAME[:UNIT]",
              help="Channel for a role (time, angle, torque; or displacement, force); repeatable.")
@click.option("--params", "params_path", type=click.Path(),
              help="TOML with [initial], [bounds], [options] (see below).")
@click.option("--holdout", type=click.Path(), help="Record kept out of the fit, for the hold-out RMSE.")
@record_time_options
@click.option("--out", type=click.Path(dir_okay=False), help="Write the identified coupling (TOML) here.")
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON.")
@click.option("--plot", "plot_dir", type=click.Path(file_okay=False), help="Write torque and loop plots to this folder.")
@click.option("--from-drop-tests", "drops", is_flag=True,
              help="DATA are drop-test logs or campaign folders: fit the model to the free decays.")
@click.option("--template", help="Coupling TOML or preset whose numbers --family template scales.")
@drop_options
@click.option("--predict-servo", type=click.Path(dir_okay=False),
              help="Drop tests: write the fitted model's servo K' and loss factor next to the drop tower's values.")
@click.option("-v", "--verbose", is_flag=True,
              help="Drop tests: a line per test (its error) and every excluded test; else a summary line.")
@click.option("--accept-poor", is_flag=True,
              help="Exit 0 and write --out even when the verdict is 'poor fit' (default: exit code 3, nothing written).")
@uncertainty_option
def identify(data: tuple[str, ...], kind: str, channels: tuple[str, ...], params_path: str | None,
             holdout: str | None, sample_rate_hz: float | None, sample_interval_s: float | None, out: str | None,
             as_json: bool, plot_dir: str | None, drops: bool,
             template: str | None, holdout_fraction: float, rig: str | None, inertia_kgm2: float | None,
             lever_length_m: float | None, sensor_radius_m: float | None, conditions: str | None,
             condition_columns: tuple[str, ...], conditions_pattern: str | None, predict_servo: str | None,
             verbose: bool, accept_poor: bool, uncertainty_specs: tuple[str, ...] = ()) -> None:
    """Identify a coupling model (its family given by --family) from imposed-angle / measured-torque DATA,
    or imposed-displacement / measured-force DATA (translational: mounts, bushings, dampers;
    any length and force units, e.g. mm, in, kN, kip; parameters then named k1_n_per_m, ...
    and --out writes a coupling with units = "translational", in N/m and N*s/m).

    Bounded trust-region-reflective least squares on the torque error, preceded by the
    family's staged strategy (the five source papers in docs/references.md). Reports the parameters with standard errors,
    parameters on a bound, the RMSE normalised by the largest |torque| on the fitting and the
    hold-out data, the residual's lag-1 correlation and the effort. A fit that does not
    converge is reported and nothing is written (exit code 2). Where the staged fit is poor,
    a global search (Latin-hypercube candidates over the whole bounds, least squares from the
    best three) follows and the better fit is kept; zerodim20 starts from zerodim6 identified
    first, and its global search is zerodim6's followed by its 20-parameter fit.

    The verdict: the fit's RMS error against the data's noise floor (estimated without a
    model: the residual of a local polynomial smoothing of the torque; for drop tests the angle's
    pre-trigger noise plus the re-simulation's accuracy), with the fitted model's own
    integration error at the data's step added (the model re-simulated on half the step:
    docs/theory.md#verdict). An error above 2 times it, or a
    parameter on a bound, is a "poor fit" with the reasons: nothing is written and the exit
    code is 3, unless --accept-poor.

    With --from-drop-tests, DATA are drop-test logs or campaign folders: every test is
    re-simulated from its impact (the lever J driven by the coupling alone, its initial rate
    from the impact-force impulse or the angle's slope) and the model (elastoslide, zerodim6,
    masing, pfeffer, or template with --template COUPLING) is fitted to the measured angle (and
    torque) decays; a fraction of the tests is held out; --predict-servo writes the fitted
    model's servo K' and loss factor next to the drop tower's first-cycle values. With
    --uncertainty (or the rig file's [uncertainty]) each parameter also gets its budget: the
    fit's standard error, each input's share (the identification's shift when that input is off
    by its standard uncertainty: J, lever, laser, flange, force sensor, clock), U95 (k = 2) and
    the dominant term.

    Time stamps printed with few decimals (steps that differ only by the printed precision)
    are taken as a constant sample rate estimated from the whole record (a note says so).
    Records without a time channel (published quasi-static tests: displacement and force
    only, amplitude blocks ramping up from rest) take --sample-interval-s or --sample-rate-hz,
    read as evaluate-servo reads them.

    --params INIT.toml (parameter names as in the report; for translational records either
    naming, k1_n_per_m or k1_nm_per_rad):

    \b
      [initial]                   # starting values
      k1_nm_per_rad = 8000.0
      [bounds]                    # [lower, upper]
      tau2_s = [0.5, 100.0]
      [options]                   # family options; every family: max_nfev, skip_s, substeps
      tau_split_s = 0.1

    \b
    Examples:
      droptower identify sweep.csv --family zerodim6 --out my_coupling.toml
      droptower identify bench.bin --family elastoslide --channel angle=Winkel:deg \\
          --channel torque=Md:kN*m --holdout check.csv --plot fits/
      droptower identify damper_sine_*.csv --family elastoslide --channel displacement=Stroke:in \\
          --channel force=Load:kip --holdout damper_random.csv --out damper.toml
      droptower identify bearing_blocks.csv --family filled_rubber --sample-interval-s 0.01 \\
          --channel displacement=d:cm --channel force=f:tonf --holdout bearing_whole.csv
      droptower identify --from-drop-tests runs/table2 --family template \\
          --template rapp2022_nr60 --out fitted.toml --predict-servo servo.csv
    """
    init = _read_init(params_path)
    check_positive(inertia_kgm2, "--inertia-kgm2")
    check_positive(lever_length_m, "--lever-length-m")
    check_positive(sensor_radius_m, "--sensor-radius-m")
    if drops:
        from droptower.cli.identify_drops_cmd import run as run_drops

        _refuse_time_base_for_drops(sample_rate_hz, sample_interval_s)

        return run_drops(data, kind, channels, init, template, holdout_fraction, rig, inertia_kgm2, lever_length_m,
                         out, as_json, plot_dir, predict_servo, verbose, accept_poor, sensor_radius_m=sensor_radius_m,
                         conditions=(conditions, condition_columns, conditions_pattern),
                         uncertainty_specs=uncertainty_specs)
    if uncertainty_specs:
        raise DroptowerError("--uncertainty gives the drop tower's input uncertainties: use it with --from-drop-tests")
    if conditions is not None or conditions_pattern is not None:
        raise DroptowerError("--conditions and --conditions-from-names give drop tests' conditions: use them with "
                             "--from-drop-tests")
    from droptower.identify.report import plot_identification
    from droptower.identify.strategies import identify as run

    if template is not None:
        init.options["template"] = template
    skip_s = float(init.options.get("skip_s", 0.0))
    segments = _read_data(data, channels, skip_s, sample_rate_hz, sample_interval_s)
    held = _read_data((holdout,), channels, skip_s, sample_rate_hz, sample_interval_s) if holdout else None
    progress(f"identify: fitting {kind} to {len(segments)} record(s) ...")
    start = time.perf_counter()
    result = run(kind, segments, init=init.initial, bounds=init.bounds, options=init.options, holdout=held,
                 file=params_path)
    progress(f"identify: {kind} done in {time.perf_counter() - start:.1f} s")
    click.echo(json.dumps(result.to_dict(), indent=1) if as_json else result.summary())
    if plot_dir:
        for path in plot_identification(result, segments, plot_dir, held):
            wrote(path, "fit over time and loops")
    if not result.converged:
        bad = next(s for s in result.stages if not s.converged)
        raise DroptowerError(f"family {kind}: the fit did not converge (stage '{bad.stage}': {bad.message}); "
                             f"no coupling written", where=None)
    if result.verdict.poor and not accept_poor:
        from droptower.identify.verdict import EXIT_POOR_FIT

        click.echo(f"droptower: family {kind}: poor fit ({'; '.join(result.verdict.reasons)}); no coupling written "
                   f"(--accept-poor writes it; exit code {EXIT_POOR_FIT})", err=True)
        raise click.exceptions.Exit(EXIT_POOR_FIT)
    if out:
        result.write_coupling(out, [Path(p).name for p in data])
        wrote(out, f"coupling {kind}, for simulate, campaign, servo")


@click.command()
@quiet_option
@click.argument("data", nargs=-1, required=True, type=click.Path(readable=False))
@click.option("--channel", "channels", multiple=True, metavar="ROLE=NAME[:UNIT]",
              help="Channel for a role (time, angle, torque; or displacement, force); repeatable.")
@click.option("--holdout", type=click.Path(),
              help="Record kept out of every fit: the families are ranked by their nRMSE on it (the BIC on the "
                   "fitting data beside it).")
@record_time_options
@renamed_option("--families", "--models", "models", announce=True,
                help=f"Families to fit, comma-separated (default: {', '.join(FAMILY_NAMES)}; with --from-drop-tests "
                   f"{', '.join(DROP_FAMILY_NAMES)}, and template with --template).")
@click.option("--out", type=click.Path(dir_okay=False, path_type=Path),
              help="Write the ranking to this table (.csv, .parquet, .json, .xlsx) and the per-record table "
                   "beside it (<name>_per_record.<suffix>).")
@click.option("--json", "as_json", is_flag=True, help="Print the tables as JSON.")
@click.option("--plot", "plot_dir", type=click.Path(file_okay=False),
              help="Write the RMSE bars (the zero-dimensional model paper, Fig. 8) and the overlaid loops to this folder.")
@click.option("--from-drop-tests", "drops", is_flag=True,
              help="DATA are drop-test logs or campaign folders: rank the families fitted to the free decays.")
@click.option("--template", help="Drop tests: also rank --family template with this coupling TOML or preset.")
@drop_options
@click.option("--budget-s", type=float, default=DEFAULT_BUDGET_S, show_default=True,
              help="Wall-time budget of each family's fit (s); a family over it is listed 'not converged' and ranked "
                   "last.")
@click.option("--total-budget-s", type=float, default=DEFAULT_TOTAL_BUDGET_S, show_default=True,
              help="Wall-time budget of all the fits together (s): each family gets at most an equal share of what "
                   "is left (the cheaper families first).")
@click.option("--accept-poor", is_flag=True, help="Exit 0 even when the best-ranked family's verdict is 'poor fit'.")
def compare_models(data: tuple[str, ...], channels: tuple[str, ...], holdout: str | None,
                   sample_rate_hz: float | None, sample_interval_s: float | None, models: str | None,
                   out: Path | None, as_json: bool, plot_dir: str | None, drops: bool, template: str | None,
                   holdout_fraction: float, rig: str | None, inertia_kgm2: float | None, lever_length_m: float | None,
                   sensor_radius_m: float | None, conditions: str | None, condition_columns: tuple[str, ...],
                   conditions_pattern: str | None, budget_s: float, total_budget_s: float, accept_poor: bool) -> None:
    """Fit every model family on the same DATA (torsional or translational servo records, or with
    --from-drop-tests drop-test logs) and rank them.

    Prints a ranking (parameters, nRMSE on the fitting and hold-out data, BIC, verdict, fit
    time), best first by one criterion for all families: BIC = n_eff ln(RSS / (n sigma^2)) +
    k ln(n_eff) on the same n fitting samples, sigma the data's noise floor and n_eff one
    effective sample size from the noise (never from a family's own residual); a family with
    more parameters ranks higher only if it lowers the error by more than its parameters cost;
    within 2 of each other families are tied and the one with fewer parameters ranks first
    (delta_bic: distance to the best; above 10: strong evidence against). It also prints the zero-dimensional model paper's Fig. 8 as a table (per record: RMSE in percent of the largest torque, and
    relative to the worst model on that record). A family whose data requirement these
    records do not meet (overlay: steady sine blocks at several amplitudes and frequencies)
    is skipped with the reason and the others are ranked. Each family's fit has a wall-time
    budget (--budget-s): a family that does not converge within it, or whose optimiser stops at
    its evaluation limit, is listed with status 'not converged' (the reason in 'note') and
    ranked after every converged family; the table is always complete. With --holdout the
    families are ranked by their error on that record, which none of them was fitted to (the
    BIC on the fitting data beside it): a richer family must predict better, not fit better.

    \b
    Exit code: 0 when the best-ranked converged family is a good fit; 3 when it is a "poor
    fit" (no family describes the data to within 2 times the noise), unless --accept-poor;
    2 when no family converged (or bad input).

    \b
    With --from-drop-tests, DATA are drop-test logs or campaign folders: every family
    (elastoslide, zerodim6, masing, pfeffer, filled_rubber; template with --template) is fitted to the same
    fitting tests' free decays and ranked by the same criterion on the angle error (sigma:
    the logs' pre-trigger noise with the re-simulation's accuracy).

    \b
    Examples:
      droptower compare-models sweep_*.csv --holdout check.csv --plot compare/
      droptower compare-models sweep.csv --families zerodim6,elastoslide --out ranking.xlsx
      droptower compare-models bearing_blocks.csv --holdout bearing_whole.csv --sample-interval-s 0.01 \\
          --channel displacement=d:cm --channel force=f:tonf --families filled_rubber,elastoslide,masing
      droptower compare-models --from-drop-tests runs/campaign --template rapp2022_nr60
    """
    from droptower.identify.ranking import compare_models as run
    from droptower.identify.report import plot_comparison
    from droptower.io.tables import check_table_path, write_table

    known = DROP_FAMILY_NAMES + ("template",) if drops else FAMILY_NAMES
    default = DROP_FAMILY_NAMES + (("template",) if template else ()) if drops else FAMILY_NAMES
    kinds = [k.strip() for k in models.split(",") if k.strip()] if models is not None else list(default)
    unknown = [k for k in kinds if k not in known]
    if unknown or not kinds:
        raise DroptowerError(f"unknown model famil{'ies' if len(unknown) > 1 else 'y'} {', '.join(unknown)} "
                             f"(known: {', '.join(known)})" if unknown else "no model family given",
                             where="--families")
    check_positive(budget_s, "--budget-s")
    check_positive(total_budget_s, "--total-budget-s")
    if out is not None:
        check_table_path(out, "--out")
    on_skip = lambda kind, why: progress(f"skipped {kind}: {cli_text(why)}")  # noqa: E731
    if drops:
        from droptower.cli.identify_drops_cmd import prepare

        _refuse_time_base_for_drops(sample_rate_hz, sample_interval_s)
        campaign = prepare(data, None, channels, InitFile(), template, holdout_fraction, rig, inertia_kgm2,
                           lever_length_m, sensor_radius_m=sensor_radius_m,
                           conditions=(conditions, condition_columns, conditions_pattern))
        decays, options = campaign.decays, campaign.options
        if "template" in kinds and "template" not in options:
            raise DroptowerError("--families template needs --template COUPLING (a preset name or a coupling TOML)")
        result = run(decays, kinds, budget_s=budget_s, total_budget_s=total_budget_s, excluded=campaign.excluded,
                     settings=campaign.settings,
                     options={"template": {"template": options["template"]}}
                     if "template" in options and "template" in kinds else None,
                     on_family=lambda kind: progress(f"compare-models: fitting {kind} to {len(decays)} drop test(s) ..."),
                     on_skip=on_skip)
        segments, held = [], None
    else:
        segments = _read_data(data, channels, 0.0, sample_rate_hz, sample_interval_s)
        held = _read_data((holdout,), channels, 0.0, sample_rate_hz, sample_interval_s) if holdout else None
        result = run(segments, kinds, holdout=held, budget_s=budget_s, total_budget_s=total_budget_s,
                     on_family=lambda kind: progress(f"compare-models: fitting {kind} to {len(segments)} record(s) ..."),
                     on_skip=on_skip)
    ranking, records = result.ranking, result.records
    if out is not None:
        wrote(write_table(ranking.rename_axis("rank").reset_index(), out, "--out"), f"ranking of {len(ranking)} families")
        if records is not None:
            wrote(write_table(records, out.with_name(f"{out.stem}_per_record{out.suffix}"), "--out"),
                  f"per record, {len(records)} rows")
    if as_json:
        click.echo(json.dumps(result.to_dict(), indent=1))
    elif drops:
        click.echo(f"ranking ({result.rule}; angle nRMSE: RMS angle error in % of each test's peak, RMS over tests):")
        click.echo(ranking.to_string(float_format=lambda v: f"{v:.4g}"))
    else:
        click.echo(f"ranking ({result.rule}; nRMSE: RMSE in % of the largest |torque|):")
        click.echo(ranking.to_string(float_format=lambda v: f"{v:.3f}"))
        click.echo("\nper record (the zero-dimensional model paper, Fig. 8): nRMSE % / RMSE relative to the worst model")
        if not records.empty:
            pct = records.pivot(index="record", columns="family", values="nrmse_percent")
            rel = records.pivot(index="record", columns="family", values="rmse_over_max_rmse")
            click.echo(pct.round(3).astype(str).add(" / ").add(rel.round(2).astype(str)).to_string())
    if plot_dir and result.results and not drops:
        loop_segment = (held or segments)[0]
        for path in plot_comparison(result.results, records, loop_segment, plot_dir):
            wrote(path, "comparison")
    if result.skipped:
        n = len(result.skipped)
        click.echo(f"droptower: skipped {n} famil{'ies' if n > 1 else 'y'} (data requirement not met): "
                   + "; ".join(f"{k}: {v}" for k, v in result.skipped.items()), err=True)
    for kind, why in result.not_converged.items():
        click.echo(f"droptower: not converged: {kind}: {why} (ranked last)", err=True)
    code = result.exit_code(accept_poor)
    if code:
        from droptower.identify.verdict import EXIT_POOR_FIT

        if code == EXIT_POOR_FIT:
            click.echo(f"droptower: the best-ranked family {result.best} is a poor fit: no family describes these data "
                       f"to within the noise (--accept-poor: exit 0; exit code {EXIT_POOR_FIT})", err=True)
        else:
            click.echo(f"droptower: no family converged (within {budget_s:g} s each); exit code {code}", err=True)
        raise click.exceptions.Exit(code)
