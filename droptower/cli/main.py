"""The ``droptower`` command: one sub-command per step of the data path.

Sub-commands are imported only when used (numba, pymunk and matplotlib are slow to import),
so ``droptower --help`` stays instant. Every user error is a :class:`DroptowerError`,
printed as one line on stderr with exit code 2 and no traceback.
"""
from __future__ import annotations

import importlib
import importlib.util
import os
import sys

import click

from droptower.cli import options
from droptower.errors import DroptowerError
from droptower.cli.flags import cli_message

#: name -> (module, attribute, one-line help). Data flows top to bottom.
COMMANDS: dict[str, tuple[str, str, str]] = {
    "servo": ("droptower.cli.servo_cmd", "servo", "Drive a coupling on the virtual servo-hydraulic bench."),
    "evaluate-servo": ("droptower.cli.servo_records_cmd", "evaluate_servo",
                       "Evaluate raw servo time records: K', K'', loss factor per block."),
    "simulate": ("droptower.cli.simulate_cmd", "simulate", "Simulate one drop test on the virtual drop tower."),
    "design": ("droptower.cli.design_cmd", "design", "Design a campaign that covers a target amplitude-frequency region."),
    "planner": ("droptower.cli.planner_cmd", "planner", "Write the interactive planner page (offline HTML)."),
    "plan": ("droptower.cli.plan_cmd", "plan", "Predict a test plan: amplitudes, frequencies, double impacts."),
    "channels": ("droptower.cli.channels_cmd", "channels", "List the channels a log file holds."),
    "extract": ("droptower.cli.extract_cmd", "extract", "Extract stiffness and damping from drop-test logs."),
    "rig": ("droptower.cli.rig_cmd", "rig", "Write a rig file from a lab's numbers, or check one."),
    "campaign": ("droptower.cli.campaign_cmd", "campaign", "Simulate, log and extract a whole test plan."),
    "map": ("droptower.cli.map_cmd", "map_command", "Fit the characteristic map (Rapp et al. 2022, eq. 19-20)."),
    "report": ("droptower.cli.report_cmd", "report", "Write an HTML report of a campaign or a results table."),
    "validate": ("droptower.cli.validate_cmd", "validate", "Compare a map with servo-hydraulic sweeps."),
    "identify": ("droptower.cli.identify_cmd", "identify", "Identify a coupling model from torque-angle data."),
    "compare-models": ("droptower.cli.identify_cmd", "compare_models", "Fit every model family and rank them."),
    "export-fmu": ("droptower.cli.fmu_cmd", "export_fmu", "Export a coupling as an FMI 2.0 co-simulation FMU."),
}


class LazyGroup(click.Group):
    """A group whose sub-commands are imported on first use."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        return [name for name, (module, _, _) in COMMANDS.items() if importlib.util.find_spec(module) is not None]

    def get_command(self, ctx: click.Context, name: str) -> click.Command | None:
        if name not in COMMANDS:
            return None
        module, attr, _ = COMMANDS[name]
        return getattr(importlib.import_module(module), attr)

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        rows = [(name, COMMANDS[name][2]) for name in self.list_commands(ctx)]
        with formatter.section("Commands"):
            formatter.write_dl(rows)


@click.group(cls=LazyGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="droptower")
@options.quiet_option
def cli() -> None:
    """droptower: a virtual drop-tower rig and parameter extractor for elastomer couplings.

    SI units inside (rad, N*m, s, kg, m); degrees only at the edges, and every output field
    names its unit. Plots: commands about one test or one table (simulate, plan, servo) take
    --plot FILE.png; commands that draw several figures (extract, map, identify,
    compare-models; validate --out) take a folder. Tables are written in the format of the
    file's suffix (.csv, .parquet, .json, .xlsx).

    \b
    Examples:
      droptower plan --out plan.xlsx
      droptower campaign --out runs/table2 && droptower map runs/table2 --out map.json
      droptower simulate --inertia-kgm2 0.359 --drop-mass-kg 2 --height-m 1 --plot test.png
    """


def main(argv: list[str] | None = None) -> int:
    """Entry point of the console script; returns the exit code."""
    args = sys.argv[1:] if argv is None else list(argv)
    if not args:  # bare `droptower` is a request for help, not a usage error
        args = ["--help"]
    options.QUIET = False  # main() may run several times in one process (tests)
    try:
        # without standalone mode, click returns the code of a command's Exit(code)
        code = cli.main(args=args, prog_name="droptower", standalone_mode=False)
    except DroptowerError as exc:
        click.echo(f"droptower: error: {cli_message(exc)}", err=True)
        return 2
    except click.exceptions.Abort:
        click.echo("droptower: aborted", err=True)
        return 130
    except click.UsageError as exc:  # one line, like every other user error
        where = f"droptower {exc.ctx.info_name}" if exc.ctx is not None and exc.ctx.parent is not None else "droptower"
        click.echo(f"droptower: error: {exc.format_message()} (see: {where} --help)", err=True)
        return 2
    except click.ClickException as exc:
        exc.show()
        return 2
    except click.exceptions.Exit as exc:
        return exc.exit_code
    except OSError as exc:  # the system refused a read or write (full disk, permissions) outside the atomic writer
        where = f"{exc.filename}: " if exc.filename else ""
        click.echo(f"droptower: error: {where}{exc.strerror or exc}", err=True)
        return 2
    return code if isinstance(code, int) else 0


def run() -> None:
    """The console script: :func:`main`, then leave without the interpreter's teardown.

    Native thread pools (Arrow's readers and writers, numba's) may still hold threads when the
    interpreter finalises; tearing them down then aborted the process now and then ("terminate
    called without an active exception", exit 134) after the command had written everything
    (apache/arrow#34314). Every file is written and closed by then, so the streams are flushed
    and the process ends with the command's exit code at once."""
    code = main()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # a closed pipe: nothing more can be said
            pass
    os._exit(code)


if __name__ == "__main__":
    run()
