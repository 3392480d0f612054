"""Options shared by the sub-commands: physical flags renamed to carry their unit, ``--quiet``.

A physical flag names its unit (``--inertia-kgm2``); its name of release 0.1 (``--inertia``)
still works for one release as a hidden alias, so existing scripts keep running.
"""
from __future__ import annotations

import sys
from collections.abc import Callable
from typing import Any

import click

#: set by ``--quiet`` (on ``droptower`` or any sub-command): no progress bars, no notes
QUIET = False


def renamed_option(name: str, old: str, dest: str, *, required: bool = False, announce: bool = False,
                   **kwargs: Any) -> Callable:
    """``@click.option(name, dest, **kwargs)`` (default None) plus ``old`` as a hidden alias of it.
    ``required`` is checked across both names (say so in ``help``: click's mark needs one name);
    ``announce``: the old name, when used, prints a deprecation note on stderr."""

    def take_new(ctx: click.Context, param: click.Parameter, value: Any) -> Any:
        if value is not None and ctx.params.get(dest) not in (None, value):
            raise click.BadParameter(f"given twice, as {name} and as its old name {old}", ctx=ctx, param=param)
        if value is None:
            value = ctx.params.get(dest)  # given under the old name (parsed first: it was on the line)
        if value is None and required:
            raise click.MissingParameter(ctx=ctx, param=param)
        return value

    def take_old(ctx: click.Context, param: click.Parameter, value: Any) -> None:
        if value is None:
            return
        if ctx.params.get(dest) not in (None, value):
            raise click.BadParameter(f"given twice, as {name} and as its old name {old}", ctx=ctx, param=param)
        if announce:  # a warning: --quiet keeps it
            click.echo(f"droptower: warning: {old} is deprecated and will be removed in the next release: use {name}",
                       err=True)
        ctx.params[dest] = value

    def decorate(f: Callable) -> Callable:
        f = click.option(old, f"{dest}_alias", hidden=True, type=kwargs.get("type"), default=None,
                         expose_value=False, callback=take_old)(f)
        return click.option(name, dest, default=None, callback=take_new, **kwargs)(f)

    return decorate


def _set_quiet(ctx: click.Context, param: click.Parameter, value: bool) -> None:
    global QUIET
    QUIET = QUIET or value


def quiet_option(f: Callable) -> Callable:
    """``-q/--quiet``: no progress bars and no notes on stderr (warnings and errors stay)."""
    return click.option("-q", "--quiet", is_flag=True, expose_value=False, is_eager=True, callback=_set_quiet,
                        help="No progress bars and no notes on stderr (warnings, errors and results stay).")(f)


def progress_disabled() -> bool | None:
    """tqdm's ``disable``: True with --quiet, else None (a bar only on a terminal)."""
    return True if QUIET else None


def progress(text: str) -> None:
    """A progress line on stderr, like tqdm's bars only on a terminal and not with --quiet."""
    if not QUIET and sys.stderr.isatty():
        click.echo(f"droptower: {text}", err=True)


def note(text: str) -> None:
    """An informational line on stderr (``droptower: note: ...``), silenced by --quiet."""
    if not QUIET:
        click.echo(f"droptower: {text}", err=True)


def wrote(path: object, what: str) -> None:
    """The one summary line of every file or folder a command writes (stderr, so ``--json`` on
    stdout stays clean; silenced by --quiet): ``droptower: wrote PATH (WHAT)``."""
    note(f"wrote {path} ({what})")


# ------------------------------------------------------------------ per-file conditions and the rig
def conditions_options(f: Callable) -> Callable:
    """``--conditions TABLE``, ``--condition-column ROLE=COLUMN[:UNIT]`` (repeatable) and
    ``--conditions-from-names PATTERN``: a command's per-file test conditions (parameters
    ``conditions``, ``condition_columns``, ``conditions_pattern``; build them with
    :func:`conditions_from_cli`)."""
    f = click.option("--conditions-from-names", "conditions_pattern", default=None, metavar="PATTERN",
                     help="Read each file's conditions from its name, e.g. "
                          "'{fixture}_m{drop_mass_kg}_h{drop_height_mm}_rep{repeat}' (fields: fixture, inertia_kgm2, "
                          "drop_mass_kg, drop_height_m, preload_nm, specimen, repeat, temperature_c; a unit suffix "
                          "like _mm or ':mm' for the name's unit).")(f)
    f = click.option("--condition-column", "condition_columns", multiple=True, metavar="ROLE=COLUMN[:UNIT]",
                     help="Map a column of --conditions to a role: file, fixture, inertia_kgm2, drop_mass_kg, "
                          "drop_height_m, preload_nm, specimen, repeat, temperature_c (repeatable; common English "
                          "and German names are found without it).")(f)
    return click.option("--conditions", "conditions", default=None, metavar="TABLE",
                        type=click.Path(dir_okay=False, path_type=str),
                        help="Per-file test conditions: a table (CSV in any dialect, .xlsx, .parquet) with one row "
                             "per log, keyed by file name or path relative to the folder: fixture or inertia, drop "
                             "mass, drop height, preload, specimen, repeat, temperature. Over each log's metadata.")(f)


def lab_log_options(f: Callable) -> Callable:
    """How a command reads a lab's logs: ``--rig``, ``--sensor-radius-m``, ``--channel``,
    ``--inertia-kgm2``, ``--lever-length-m`` (parameters ``rig``, ``sensor_radius_m``,
    ``channel_specs``, ``inertia_kgm2``, ``lever_length_m``) and :func:`conditions_options`: the
    same flags, with the same meaning, on every command that reads logs (map, validate, report)."""
    f = conditions_options(f)
    f = click.option("--lever-length-m", type=float, default=None,
                     help="Lever arm L in m of a lab's logs (over their metadata and the rig's).")(f)
    f = click.option("--inertia-kgm2", type=float, default=None,
                     help="Rotating inertia J in kg*m^2 of every log (a lab's logs; else their metadata, --conditions "
                          "or a rig with a single fixture).")(f)
    f = click.option("--channel", "channel_specs", multiple=True, metavar="ROLE=NAME[:UNIT]",
                     help="Channel mapping for reading a lab's logs (as droptower extract --channel).")(f)
    f = click.option("--sensor-radius-m", type=float, default=None,
                     help="Laser spot radius in m for a distance channel of a lab's logs (over the rig's).")(f)
    return click.option("--rig", default=None,
                        help="Rig TOML (or shipped preset) of a lab's logs: lever length, laser radius, fixtures "
                             "(as extract --rig).")(f)


def _cli_columns_text(exc: Exception) -> Exception:
    """A conditions error as the command line says it: ``--condition-column`` for ``columns=``."""
    from droptower.errors import DroptowerError

    if isinstance(exc, DroptowerError) and "`columns=" in exc.problem:
        import re

        problem = re.sub(r"`columns=\{'(\w+)': '([^']*)'\}`", r"--condition-column \1=\2", exc.problem)
        return DroptowerError(problem, file=exc.file, where=exc.where)
    return exc


def conditions_from_cli(table: str | None, column_specs: tuple[str, ...] | list[str], pattern: str | None,
                        rig: Any = None) -> Any:
    """The :class:`~droptower.io.conditions.Conditions` the flags ask for (None without
    ``--conditions`` and ``--conditions-from-names``); the table's bad rows are printed once as
    warnings (each fails only its own file), its notes as notes. ``rig``: a loaded RigConfig
    whose named fixtures give a fixture's inertia."""
    from droptower.errors import DroptowerError
    from droptower.io.conditions import conditions_from_names, parse_condition_columns, read_conditions

    if table is not None and pattern is not None:
        raise DroptowerError("give --conditions or --conditions-from-names, not both")
    if column_specs and table is None:
        raise DroptowerError("--condition-column maps the columns of --conditions, which is not given")
    if table is None and pattern is None:
        return None
    try:
        if pattern is not None:
            return conditions_from_names(pattern, rig=rig)
        conditions = read_conditions(table, columns=parse_condition_columns(column_specs), rig=rig)
    except DroptowerError as exc:
        raise _cli_columns_text(exc) from None
    for line in conditions.problems:
        click.echo(f"droptower: warning: {line}", err=True)
    for line in conditions.notes:
        note(f"note: {line}")
    return conditions


def _written_by_droptower(path: str) -> bool:
    """True if the log at ``path`` is one droptower wrote (its own log format), False for any
    other file (or one that cannot be opened: the reader reports that)."""
    from pathlib import Path

    from droptower.io.droptower_log import is_droptower_csv, parquet_metadata

    p = Path(path)
    try:
        if p.suffix.lower() == ".parquet":
            return parquet_metadata(p) is not None
        return is_droptower_csv(p)
    except Exception:  # unreadable: not droptower's; the reader names the problem
        return False


def rig_for_logs(rig: str | None, paths: tuple[str, ...] | list[str] = ()) -> Any:
    """Load ``--rig`` for a command that reads logs and print the geometry it gives once to
    stderr (``droptower: geometry: ...``: lever length, laser radius, fixtures and where they
    came from). A shipped preset used on logs droptower did not write is a warning (a lab's
    rig is rarely the paper's). Returns the RigConfig, or None without ``--rig``."""
    if rig is None:
        return None
    from droptower.rig.config import load_rig

    config = load_rig(rig)
    foreign = [p for p in paths if not _written_by_droptower(p)]
    if config.is_preset and foreign:
        click.echo(f"droptower: warning: --rig {config.label} is a shipped preset (the rig of its paper), used on "
                   f"{len(foreign)} log(s) droptower did not write: give your own rig file (droptower rig new) "
                   f"unless these logs come from that rig; geometry: {config.geometry_text()}", err=True)
    else:
        note(f"geometry: {config.geometry_text()}")
    return config


# ------------------------------------------------------------------ input uncertainties
def uncertainty_option(f: Callable) -> Callable:
    """``--uncertainty INPUT=VALUE[:normal|rectangular]`` (repeatable), over the rig file's ``[uncertainty]``."""
    return click.option(
        "--uncertainty", "uncertainty_specs", multiple=True, metavar="INPUT=VALUE[:normal|rectangular]",
        help="An input's standard uncertainty (normal; rectangular: the half-width), over the rig file's "
             "[uncertainty] table (repeatable): lever_length_m, laser_radius_m, drop_height_m, sample_rate_hz, "
             "torque_calibration_rel, laser_calibration_rel, force_calibration_rel (relative: 0.005 = 0.5 %), or "
             "a fixture's inertia_kgm2@NOMINAL / drop_mass_kg@NOMINAL (e.g. inertia_kgm2@0.359=0.0036). Not "
             "given: the results carry the fit's uncertainty only, and say so.")(f)


def uncertainty_from_cli(specs: tuple[str, ...] | list[str], rig: Any = None) -> Any:
    """The input uncertainties of ``--uncertainty`` over ``rig.uncertainty`` (a RigUncertainty), or None."""
    from droptower.cli.flags import cli_error
    from droptower.errors import DroptowerError
    from droptower.rig.uncertainty import override_uncertainty

    try:
        return override_uncertainty(getattr(rig, "uncertainty", None), list(specs))
    except DroptowerError as exc:
        raise cli_error(exc) from None


def note_uncertainty(uncertainty: Any) -> None:
    """Say once which inputs' uncertainties the results carry, and that the rest are not given."""
    from droptower.rig.uncertainty import SPEC_NAMES

    given = [name for name, field in SPEC_NAMES.items() if uncertainty is not None and getattr(uncertainty, field)]
    if not given:
        note("note: input uncertainties: not given (the rig file's [uncertainty] or --uncertainty); the "
             "uncertainties shown are the fit's alone")
    else:
        rest = [name for name in SPEC_NAMES if name not in given]
        note(f"note: input uncertainties given: {', '.join(given)}; not given: {', '.join(rest) or 'none'}")
