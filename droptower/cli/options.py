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


def renamed_option(name: str, old: str, dest: str, *, required: bool = False, **kwargs: Any) -> Callable:
    """``@click.option(name, dest, **kwargs)`` (default None) plus ``old`` as a hidden alias of it.
    ``required`` is checked across both names (say so in ``help``: click's mark needs one name)."""

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
