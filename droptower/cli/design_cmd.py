"""``droptower design``: from the region an engineer wants measured to a test plan."""
from __future__ import annotations

import json
import math
from pathlib import Path

import click

from droptower.cli.options import note, quiet_option
from droptower.configs import DEFAULT_COUPLING, DEFAULT_RIG
from droptower.errors import DroptowerError
from droptower.jsonsafe import json_safe
from droptower.cli.flags import cli_text

#: Columns printed as the table (all are in --json).
TABLE_COLUMNS = ["case", "drop_mass_kg", "drop_height_m", "preload_nm", "repeats", "amplitude_deg",
                 "frequency_hz", "damping_ratio", "peak_torque_nm", "min_clearance_mm"]

#: The range --for-identification chooses from when no target is given: all the rig can do.
ALL_AMPLITUDES_DEG = (1e-3, 90.0)
ALL_FREQUENCIES_HZ = (0.1, 1000.0)


def _range(option: str, text: str) -> tuple[float, float]:
    """``"0.3:3"`` -> (0.3, 3.0); a single number is a range of one point."""
    try:
        parts = [float(v) for v in text.split(":")]
    except ValueError:
        raise DroptowerError(f"expected LOW:HIGH (two numbers), got {text!r}", where=option) from None
    if len(parts) == 1:
        parts *= 2
    if len(parts) != 2:
        raise DroptowerError(f"expected LOW:HIGH (two numbers), got {text!r}", where=option)
    return parts[0], parts[1]


def _preloads(text: str) -> tuple[float, ...]:
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        raise DroptowerError(f"expected comma-separated numbers (N*m), got {text!r}", where="--preloads-nm") from None
    return values


@click.command()
@quiet_option
@click.option("--amplitude-deg", default=None, help="Target amplitude range LOW:HIGH (deg), e.g. 0.3:3 (required "
              "without --for-identification; with it, the range the drops are chosen from, default all).")
@click.option("--frequency-hz", default=None, help="Target frequency range LOW:HIGH (Hz), e.g. 22:50 (as "
              "--amplitude-deg).")
@click.option("--for-identification", "model", default=None,
              help="Instead of covering the target: the --max-tests drops (default 12) that identify this model "
                   "best (D-optimal; `template` = the coupling's own structure; or zerodim6, elastoslide, masing, "
                   "pfeffer, filled_rubber), with the parameters' predicted standard errors.")
@click.option("--preloads-nm", default="0", show_default=True, help="Preloads every condition is tested at (N*m), "
              "comma-separated, e.g. 0,500,1000.")
@click.option("--repeats", type=click.IntRange(1, 1000), default=None,
              help="Repeats per condition (default 3; or --uncertainty-pct).")
@click.option("--uncertainty-pct", type=float, default=None,
              help="Instead of --repeats: enough repeats for this standard uncertainty (% of the value) of the "
                   "mean stiffness and damping ratio of every condition, from a virtual pilot test per condition.")
@click.option("--rig", default=DEFAULT_RIG, show_default=True, help="Rig TOML file or shipped preset name.")
@click.option("--coupling", default=DEFAULT_COUPLING, show_default=True,
              help="Coupling TOML file or shipped preset name (what the drops are predicted on).")
@click.option("--max-tests", type=click.IntRange(1, None), default=None,
              help="Budget of drops: repeats, then the amplitude spacing give way to it.")
@click.option("--out", required=True, type=click.Path(dir_okay=False),
              help="The test plan to write (.toml; `droptower campaign --doe` runs it as it is).")
@click.option("--sheet", type=click.Path(dir_okay=False), default=None,
              help="The lab's run sheet (.xlsx, .csv, .parquet or .json): a seeded random order blocked by "
                   "lever and mass, one row per drop, a column for the operator's notes.")
@click.option("--seed", type=int, default=0, show_default=True, help="Seed of the run order (and the plan's base seed).")
@click.option("--json", "as_json", is_flag=True, help="Print the design as JSON.")
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False), default=None,
              help="Draw the coverage of the target (PNG).")
def design(amplitude_deg: str | None, frequency_hz: str | None, model: str | None, preloads_nm: str, repeats: int | None,
           uncertainty_pct: float | None, rig: str, coupling: str, max_tests: int | None, out: str,
           sheet: str | None, seed: int, as_json: bool, plot_path: str | None) -> None:
    """Design a campaign that covers a target region of amplitude and frequency: which levers,
    drop masses and heights of the rig, at which preloads, how many repeats, in what order.

    Every drop the rig can make is predicted on the coupling (as `droptower plan` does: impact
    law, preload, double impact with a 1 mm margin, sensor ranges, twist limit, samples per
    period); the design takes the fewest levers whose drops' hull covers the reachable part of
    the target (at least three where the target spans frequencies), heights evenly spaced in log
    amplitude on each, and says which part of the target the rig cannot reach, and why.

    \b
    Examples:
      droptower design --amplitude-deg 0.3:3 --frequency-hz 22:50 --out plan.toml --plot coverage.png
      droptower design --amplitude-deg 0.3:3 --frequency-hz 22:50 --preloads-nm 0,500,1000 \\
          --uncertainty-pct 1 --out plan.toml --sheet run_order.xlsx
      droptower campaign --doe plan.toml --out runs/designed
      droptower design --for-identification template --max-tests 12 --out ident.toml
    """
    # imported here, not at the top: the design predicts drops on the rig (numba, pymunk, scipy),
    # which `droptower design --help` and `droptower planner` (importing _preloads) do not need
    from droptower.design import Target, design_campaign
    from droptower.design.outputs import coverage_description, run_sheet, write_doe
    from droptower.io.tables import check_table_path, write_table
    from droptower.rheology import load_coupling
    from droptower.rig.config import load_rig

    if repeats is not None and uncertainty_pct is not None:
        raise DroptowerError("give --repeats or --uncertainty-pct, not both", where="--uncertainty-pct")
    if uncertainty_pct is not None and not (math.isfinite(uncertainty_pct) and uncertainty_pct > 0):
        raise DroptowerError(f"must be a positive number, got {uncertainty_pct:g}", where="--uncertainty-pct")
    if Path(out).suffix.lower() != ".toml":
        raise DroptowerError("the test plan is a TOML file: give a name ending in .toml", file=out, where="--out")
    if sheet:
        check_table_path(sheet, "--sheet")
    if model is None:
        for flag, value in (("--amplitude-deg", amplitude_deg), ("--frequency-hz", frequency_hz)):
            if value is None:
                raise DroptowerError("the target region is required (or --for-identification MODEL)", where=flag)
    target = Target(_range("--amplitude-deg", amplitude_deg or f"{ALL_AMPLITUDES_DEG[0]}:{ALL_AMPLITUDES_DEG[1]}"),
                    _range("--frequency-hz", frequency_hz or f"{ALL_FREQUENCIES_HZ[0]}:{ALL_FREQUENCIES_HZ[1]}"),
                    _preloads(preloads_nm))
    rig_cfg = load_rig(rig)
    for p in target.preloads_nm:
        lo, hi = rig_cfg.preload_range_nm
        if not lo <= p <= hi:
            raise DroptowerError(f"preload {p:g} N*m is outside the range {lo:g}-{hi:g} N*m of rig {rig_cfg.name}",
                                 where="--preloads-nm")
    coupling_model = load_coupling(coupling)
    if model is not None:
        _identification(rig_cfg, coupling_model, target, model, max_tests or 12, out, sheet, seed, as_json)
        return
    result = design_campaign(rig_cfg, coupling_model, target, repeats=repeats or 3, max_tests=max_tests)
    if uncertainty_pct is not None:
        from droptower.design.repeats import pilot_uncertainty, repeats_for

        note(f"pilot: one virtual test per condition ({result.n_conditions}) for the scatter of c and d")
        n = repeats_for(pilot_uncertainty(result, rig, coupling), uncertainty_pct)
        result = design_campaign(rig_cfg, coupling_model, target, repeats=n, max_tests=max_tests,
                                 candidates=result.candidates)
    plan_file = write_doe(result.conditions, out, coverage_description(result), base_seed=seed)
    if sheet:
        write_table(run_sheet(result.conditions, seed), sheet, "--sheet")
    if plot_path:
        from droptower.design.plots import plot_coverage

        plot_coverage(result, plot_path, f"{coupling_model.name} on {rig_cfg.name}: "
                                         f"{100 * result.covered_fraction:.0f} % of the target covered")
    if as_json:
        click.echo(json.dumps(json_safe({
            "tests": result.n_tests, "conditions": _records(result.conditions),
            "target_covered_fraction": result.covered_fraction, "reachable_fraction": result.reachable_fraction,
            "unreachable": result.unreachable, "double_impacts_predicted": result.double_impacts_predicted,
            "limits_hit": [cli_text(line) for line in result.limits_hit], "repeats": result.repeats, "plan_file": str(plan_file),
            "sheet_file": sheet}), indent=1))
        return
    click.echo(f"{result.n_conditions} conditions x {result.repeats} repeats = {result.n_tests} drops on rig "
               f"{rig_cfg.name} with {coupling_model.name}; {100 * result.covered_fraction:.0f} % of the target "
               f"covered ({100 * result.reachable_fraction:.0f} % reachable with this rig)")
    _print_table(result.conditions)
    for line in result.unreachable:
        click.echo(f"unreachable: {line}")
    for line in result.limits_hit:
        click.echo(f"limit: {cli_text(line)}")
    click.echo(f"{result.double_impacts_predicted} double impact(s) predicted")
    _written(plan=plan_file, sheet=sheet, plot=plot_path)


def _identification(rig, coupling, target, model: str, n_tests: int, out: str, sheet: str | None, seed: int,
                    as_json: bool) -> None:
    from droptower.design.identification import design_for_identification
    from droptower.design.outputs import run_sheet, write_doe
    from droptower.io.tables import write_table

    result = design_for_identification(rig, coupling, target, model, n_tests)
    c = result.conditions
    plan_file = write_doe(c, out, f"designed by droptower design --for-identification {model}: {n_tests} drops "
                                  "(D-optimal)", base_seed=seed)
    if sheet:
        write_table(run_sheet(c, seed), sheet, "--sheet")
    params = {r.parameter: {"value": r.value, "std_error": r.std_error, "relative_std_error": r.relative_std_error}
              for r in result.parameters.itertuples()}
    if as_json:
        click.echo(json.dumps(json_safe({"tests": int(c["repeats"].sum()), "conditions": _records(c), "model": model,
                                         "predicted_std_errors": params, "log_det_information": result.log_det,
                                         "plan_file": str(plan_file), "sheet_file": sheet}), indent=1))
        return
    click.echo(f"{n_tests} drops that identify {model} best (D-optimal) on rig {rig.name} with {coupling.name}:")
    _print_table(c)
    click.echo("predicted standard errors (sensor noise of the rig, white):")
    with pd_options():
        click.echo(result.parameters.to_string(index=False))
    _written(plan=plan_file, sheet=sheet)


def _records(table) -> list[dict]:
    return table[[*TABLE_COLUMNS, "inertia_kgm2", "warnings"]].to_dict(orient="records")


def pd_options():
    import pandas as pd

    return pd.option_context("display.width", 200, "display.float_format", "{:.4g}".format)


def _print_table(table) -> None:
    with pd_options():
        click.echo(table[TABLE_COLUMNS].to_string(index=False))


def _written(**files) -> None:
    for key, value in files.items():
        if value:
            click.echo(f"{key}: {value}")
