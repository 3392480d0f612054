"""``droptower campaign``: a whole test plan simulated, logged and extracted (Rapp et al. 2022, Table 2)."""
from __future__ import annotations

from pathlib import Path

import click

from droptower.cli import options
from droptower.cli.options import quiet_option
from droptower.configs import DEFAULT_COUPLING, DEFAULT_DOE, DEFAULT_RIG
from droptower.errors import DroptowerError, check_positive
from droptower.cli.flags import cli_text


@click.command()
@quiet_option
@click.option("--rig", default=None,
              help=f"Rig TOML file or shipped preset name [default: {DEFAULT_RIG}; with --resume: the folder's].")
@click.option("--coupling", default=None,
              help=f"Coupling TOML file or shipped preset name [default: {DEFAULT_COUPLING}; with --resume: the "
                   f"folder's].")
@click.option("--doe", default=None,
              help=f"Test-plan TOML file or shipped preset name [default: {DEFAULT_DOE}; with --resume: the "
                   f"folder's].")
@click.option("--out", type=click.Path(path_type=Path), required=True,
              help="Campaign folder: logs/, records/, results.parquet, results.csv, manifest.json.")
@click.option("--workers", type=int, default=None, help="Local worker processes [default: every local core].")
@click.option("--scheduler", default=None, metavar="ADDRESS",
              help="Run the chunks on this Dask distributed scheduler (e.g. tcp://host:8786) instead; the "
                   "folder must be reachable by its workers under the same path.")
@click.option("--scheduler-timeout-s", type=float, default=10.0, show_default=True,
              help="How long to wait for the scheduler to answer.")
@click.option("--resume", is_flag=True, help="Continue the campaign in --out where it stopped.")
@click.option("--duration-s", type=float, default=None,
              help="Record length after the impact (s) [default: twice the longest first period the planner "
                   "predicts for the plan; with --resume: the folder's].")
@click.option("--log-format", type=click.Choice(["parquet", "csv"]), default=None,
              help="Log file format [default: parquet; with --resume: the folder's].")
@click.option("--chunk-size", type=int, default=None,
              help="Tests per batched simulation, part of the campaign's identity [default: 75; with --resume: "
                   "the folder's].")
@click.option("--estimate", is_flag=True,
              help="Only estimate the campaign's time and disk (runs its first chunk in a temporary folder); "
                   "--out is not written.")
@options.uncertainty_option
def campaign(rig: str | None, coupling: str | None, doe: str | None, out: Path, workers: int | None, scheduler: str | None,
             scheduler_timeout_s: float, resume: bool, duration_s: float | None, log_format: str | None,
             chunk_size: int | None, estimate: bool, uncertainty_specs: tuple[str, ...] = ()) -> None:
    """Simulate every test of a plan on the virtual drop tower, write its log and extract it
    from the log on disk with the code that evaluates real logs (as `droptower extract`).

    Writes OUT/results.parquet and OUT/results.csv (one row per test: plan fields, the
    extracted values under the names of `droptower extract --json`, flags, log_file),
    OUT/logs/, and OUT/manifest.json (hashes and contents of rig, coupling and plan, versions,
    per-test status). Resumable: with --resume, finished tests are kept and the rest is run,
    with the rig, coupling, plan and settings recorded in the folder's manifest (give none of
    them again); a folder holding another campaign is never touched. Same plan and seeds, same results,
    whatever the number of workers.

    With --uncertainty (the rig's stated input uncertainties: hypotheses on a virtual rig) the
    finished tests' logs are read again for their budgets and OUT/results_uncertainty.csv
    holds the results with each output's _u, _U95 (k = 2) and _dominant columns, as
    `droptower extract --uncertainty` writes them.
    A test whose simulation or extraction fails is listed at the end (exit code 2, as for
    any user error); the others are still written. Unfinished tests: exit code 2 as well.

    \b
    Examples:
      droptower campaign --out runs/table2
      droptower campaign --coupling my.toml --doe my_plan.toml --out runs/mine --workers 2
      droptower campaign --out runs/mine --resume
      droptower campaign --out runs/big --doe big_plan.toml --estimate
    """
    from droptower.campaign import run_campaign
    from droptower.campaign.folder import check_folder, has_campaign

    check_positive(duration_s, "--duration-s")
    if resume and not has_campaign(out):  # else --resume would start the default plan in it
        check_folder(out)  # a non-empty folder is named as such
        raise DroptowerError("holds no campaign to resume (no manifest.json); leave out --resume to start one",
                             file=out)
    if estimate:
        from droptower.campaign import estimate_campaign

        figures = estimate_campaign(out, rig, coupling, doe, workers=workers, scheduler=scheduler, resume=resume,
                                    duration_s=duration_s, chunk_size=chunk_size, log_format=log_format,
                                    scheduler_timeout_s=scheduler_timeout_s)
        click.echo("\n".join(figures.lines()))
        return
    try:
        run = run_campaign(out, rig, coupling, doe, workers=workers, scheduler=scheduler, resume=resume,
                           duration_s=duration_s, chunk_size=chunk_size, log_format=log_format,
                           scheduler_timeout_s=scheduler_timeout_s, progress=not options.QUIET)
    except KeyboardInterrupt:  # Ctrl-C: say what is kept (the records on disk) and how to go on
        from droptower.campaign.folder import Layout, count_finished

        if (out / "manifest.json").is_file():
            click.echo(f"droptower: interrupted; {count_finished(Layout(out))} test(s) of the campaign are finished "
                       f"and kept; continue with: droptower campaign --out {out} --resume", err=True)
        raise click.exceptions.Exit(130) from None
    for line in run.warnings:
        click.echo(f"droptower: warning: {line}", err=True)
    n = len(run.spec.tests)
    click.echo(run.summary())
    for path, what in run.outputs:
        options.wrote(path, what)
    if uncertainty_specs and not run.results.empty:
        path = _with_uncertainty(out, run, uncertainty_specs)
        options.wrote(path, "the results with each output's uncertainty (_u, _U95, _dominant)")
    if run.failed:
        click.echo(f"droptower: {len(run.failed)} of {n} test(s) failed:", err=True)
        for test_id, error in run.failed:
            click.echo(f"  test {test_id}: {cli_text(error)}", err=True)
    for line in run.errors:
        click.echo(f"droptower: error: {cli_text(line)}", err=True)
    if run.pending:
        click.echo(f"droptower: {run.pending} test(s) not finished; run again with --resume to continue", err=True)
    if run.failed or run.errors or run.pending:
        raise click.exceptions.Exit(2)


def _with_uncertainty(out: Path, run, specs: tuple[str, ...]) -> Path:
    """The campaign's results with the per-drop uncertainty columns of ``extract --uncertainty``
    (the logs read again: the budgets need the fits), written to OUT/results_uncertainty.csv."""
    import pandas as pd

    from droptower.cli.extract_cmd import _uncertainty_rows
    from droptower.cli.options import note_uncertainty, uncertainty_from_cli
    from droptower.extract.files import Settings, extract_drops
    from droptower.extract.window import Window
    from droptower.io.tables import write_table

    uncertainty = uncertainty_from_cli(specs, run.spec.rig)
    note_uncertainty(uncertainty)
    results = run.results.reset_index(drop=True)
    settings = Settings(rig=run.spec.rig, window=Window.parse(run.spec.window))
    drops = []
    for i, name in enumerate(results["log_file"]):
        if not isinstance(name, str) or not name:
            continue
        for drop in extract_drops(str(out / name), settings):
            if drop.error is None:
                drops.append((i, str(out / name), drop))
    columns = _uncertainty_rows(drops, uncertainty, run.spec.rig, "auto", None, None) if drops else []
    extra = pd.DataFrame(columns, index=[i for i, _, _ in drops])
    return write_table(results.join(extra), out / "results_uncertainty.csv", "--out")
