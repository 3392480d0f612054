"""``droptower rig new|check``: a lab's own rig file from its numbers, and a check of one
(the fields: docs/guide/rig-file.md)."""
from __future__ import annotations

from pathlib import Path

import click

from droptower.cli.options import quiet_option, wrote
from droptower.errors import DroptowerError


@click.group()
@quiet_option
def rig() -> None:
    """Write a rig file from the lab's numbers (rig new) or check one (rig check).

    A rig file gives extraction the lever length, the laser radius and the named lever fixtures
    (`droptower extract --rig FILE`); every field: docs/guide/rig-file.md.

    \b
    Examples:
      droptower rig new lab_rig.toml --lever-length-m 0.25 --laser-radius-m 0.25 \\
          --fixture L1=0.12 --fixture L2=0.25 --drop-mass-kg 1 --sample-rate-hz 19200
      droptower rig check lab_rig.toml
    """


def _fixture(text: str) -> tuple[str, float]:
    name, sep, value = text.partition("=")
    try:
        inertia = float(value)
    except ValueError:
        inertia = float("nan")
    if not sep or not name.strip() or not inertia > 0:
        raise DroptowerError(f"--fixture {text!r}: expected NAME=INERTIA (kg*m^2, > 0), e.g. L1=0.12")
    return name.strip(), inertia


@rig.command("new")
@quiet_option
@click.argument("out", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--lever-length-m", type=float, required=True, help="Lever arm L, rotation axis to impact point, in m.")
@click.option("--laser-radius-m", type=float, required=True,
              help="Horizontal distance of the laser spot from the pivot, in m.")
@click.option("--fixture", "fixtures", multiple=True, required=True, metavar="NAME=INERTIA",
              help="A lever fixture and its rotating inertia J in kg*m^2 (repeatable), e.g. --fixture L1=0.12.")
@click.option("--drop-mass-kg", "drop_masses", type=float, multiple=True, required=True,
              help="A drop mass in kg (repeatable).")
@click.option("--sample-rate-hz", type=float, required=True, help="Sample rate of the data acquisition in Hz.")
@click.option("--name", default="", help="The rig's name (default: the file's stem).")
@click.option("--description", default="", help="One line on the rig.")
@click.option("--drop-height-range-m", type=float, nargs=2, default=None, metavar="MIN MAX",
              help="Lowest and highest drop height in m [assumed: 0.005 6].")
@click.option("--preload-range-nm", type=float, nargs=2, default=None, metavar="MIN MAX",
              help="Lowest and highest preload in N*m [assumed: 0 0].")
@click.option("--restitution", type=float, default=None, help="Restitution k of the mass-lever contact [assumed: 0.5].")
@click.option("--force", is_flag=True, help="Overwrite OUT if it exists.")
def new(out: Path, lever_length_m: float, laser_radius_m: float, fixtures: tuple[str, ...],
        drop_masses: tuple[float, ...], sample_rate_hz: float, name: str, description: str,
        drop_height_range_m: tuple[float, float] | None, preload_range_nm: tuple[float, float] | None,
        restitution: float | None, force: bool) -> None:
    """Write the rig file OUT (.toml) from the lab's numbers.

    The fields only the simulation uses (sensor noise and ranges, contact duration, time step)
    and any range not given are filled with stated assumptions, marked `# assumed: ...` in the
    file. The file is checked as `rig check` does before it is written.

    \b
    Examples:
      droptower rig new lab_rig.toml --lever-length-m 0.25 --laser-radius-m 0.25 \\
          --fixture L1=0.12 --fixture L2=0.25 --fixture L3=0.40 \\
          --drop-mass-kg 1 --drop-mass-kg 2 --sample-rate-hz 19200
    """
    from droptower.io.droptower_log import atomic_write
    from droptower.rig.config import load_rig
    from droptower.rig.rigfile import new_rig as _new_rig, rig_toml

    if out.suffix.lower() != ".toml":
        raise DroptowerError(f"a rig file is TOML: give a name ending in .toml, got '{out.name}'", where="OUT")
    if out.exists() and not force:
        raise DroptowerError("exists; give --force to overwrite it", file=out)
    named = dict(_fixture(text) for text in fixtures)
    if len(named) != len(fixtures):
        raise DroptowerError("--fixture: a fixture name given twice")
    try:
        config = _new_rig(lever_length_m=lever_length_m, laser_radius_m=laser_radius_m, fixtures=named,
                          drop_masses_kg=list(drop_masses), sample_rate_hz=sample_rate_hz, name=name or out.stem,
                          description=description,
                          drop_height_range_m=list(drop_height_range_m) if drop_height_range_m else None,
                          preload_range_nm=list(preload_range_nm) if preload_range_nm else None, restitution=restitution)
    except DroptowerError as exc:  # the parameter as this command's flag
        flag = {"fixtures": "--fixture", "drop_masses_kg": "--drop-mass-kg"}.get(
            exc.where or "", "--" + (exc.where or "").replace("_", "-"))
        raise DroptowerError(exc.problem, where=flag) from None
    text = rig_toml(config)
    out.parent.mkdir(parents=True, exist_ok=True)
    atomic_write(out, lambda tmp: Path(tmp).write_text(text, encoding="utf-8"))
    load_rig(out)  # what was written reads back
    wrote(out, f"rig {config.name}: {len(named)} fixture(s)")


@rig.command("check")
@quiet_option
@click.argument("rig_file", metavar="FILE")
def check(rig_file: str) -> None:
    """Validate the rig file FILE (or a shipped preset's name) and print the geometry extraction uses.

    \b
    Examples:
      droptower rig check lab_rig.toml
    """
    from droptower.rig.config import load_rig

    config = load_rig(rig_file)
    click.echo(f"{config.label}: valid rig file")
    click.echo(f"  lever length    {config.lever_length_m:g} m")
    click.echo(f"  laser radius    {config.sensors.laser.radius_m:g} m")
    if config.fixtures:
        for fixture, inertia in config.fixtures.items():
            click.echo(f"  fixture {fixture:<8} {inertia:g} kg*m^2")
    else:
        click.echo(f"  fixtures        {', '.join(f'{j:g}' for j in config.inertias_kgm2)} kg*m^2 (unnamed: give them "
                   "names under [fixtures] for a conditions table's fixture column)")
    click.echo(f"  drop masses     {', '.join(f'{m:g}' for m in config.drop_masses_kg)} kg")
    lo, hi = config.drop_height_range_m
    click.echo(f"  drop heights    {lo:g}-{hi:g} m")
    click.echo(f"  restitution     {config.restitution:g}")
    click.echo(f"  sample rate     {config.sensors.sample_rate_hz:g} Hz")
    if config.is_preset:
        click.echo("  (a shipped preset: the rig of its paper, not a lab's own)")
