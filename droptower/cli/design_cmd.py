"""``droptower design``: from the region an engineer wants measured to a test plan."""
from __future__ import annotations

import json

import click

from droptower.cli.options import note, quiet_option, uncertainty_from_cli, uncertainty_option
from droptower.cli.flags import cli_text
from droptower.configs import DEFAULT_COUPLING, DEFAULT_RIG
from droptower.errors import DroptowerError
from droptower.jsonsafe import json_safe


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
                   "mean stiffness and damping ratio of every condition, from a virtual pilot test per condition; "
                   "the rig's input uncertainties (--rig's [uncertainty], --uncertainty) count too: J's share does "
                   "not average out, and the design says when an input alone exceeds the target.")
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
@uncertainty_option
def design(amplitude_deg: str | None, frequency_hz: str | None, model: str | None, preloads_nm: str, repeats: int | None,
           uncertainty_pct: float | None, rig: str, coupling: str, max_tests: int | None, out: str,
           sheet: str | None, seed: int, as_json: bool, plot_path: str | None,
           uncertainty_specs: tuple[str, ...] = ()) -> None:
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
    from droptower.design import design as run_design
    from droptower.design.outputs import check_plan_paths

    check_plan_paths(out, sheet)
    input_u = None
    if uncertainty_specs:
        from droptower.rig.config import load_rig

        input_u = uncertainty_from_cli(uncertainty_specs, load_rig(rig))
    result = run_design(_range("--amplitude-deg", amplitude_deg) if amplitude_deg is not None else None,
                        _range("--frequency-hz", frequency_hz) if frequency_hz is not None else None,
                        preloads_nm=_preloads(preloads_nm), repeats=repeats, uncertainty_pct=uncertainty_pct,
                        rig=rig, coupling=coupling, max_tests=max_tests, for_identification=model, on_note=note,
                        uncertainty=input_u)
    result.write(out, sheet, seed)
    if plot_path and model is None:
        from droptower.design.plots import plot_coverage

        plot_coverage(result, plot_path, f"{result.coupling_name} on {result.rig_name}: "
                                         f"{100 * result.covered_fraction:.0f} % of the target covered")
    if as_json:
        doc = result.to_dict()
        if model is None:
            doc["limits_hit"] = [cli_text(line) for line in doc["limits_hit"]]
        click.echo(json.dumps(json_safe(doc), indent=1))
        return
    click.echo(cli_text(result.summary()))
    if model is None:
        _written(plan=result.plan_file, sheet=sheet, plot=plot_path)
    else:
        _written(plan=result.plan_file, sheet=sheet)


def _written(**files) -> None:
    for key, value in files.items():
        if value:
            click.echo(f"{key}: {value}")
