"""``droptower export-fmu COUPLING --out coupling.fmu``: a coupling as an FMI 2.0 co-simulation FMU."""
from __future__ import annotations

from pathlib import Path

import click

from droptower.cli.options import quiet_option
from droptower.errors import DroptowerError
from droptower.rates import RIG_SAMPLE_RATE_HZ


@click.command("export-fmu")
@quiet_option
@click.argument("coupling")
@click.option("--out", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="The FMU file to write (.fmu).")
@click.option("--internal-step-s", type=float, default=1.0 / RIG_SAMPLE_RATE_HZ,
              show_default=f"1/{RIG_SAMPLE_RATE_HZ:.0f} s ({RIG_SAMPLE_RATE_HZ / 1e3:g} kHz, the rig's sample rate)",
              help="Largest internal time step in s: a communication step is split into equal steps of at most this.")
def export_fmu(coupling: str, out: Path, internal_step_s: float) -> None:
    """Write COUPLING (a coupling TOML file, a shipped preset's name, or an `identify` result)
    as an FMI 2.0 co-simulation FMU for Simulink, Modelica tools, Adams, FMPy, ...

    Input angle_rad (the twist, rad) and, optionally, angle_rate_rad_per_s (rad/s: the angle is
    then extrapolated over a communication step, else held); output torque_nm (N*m); parameters
    every number of every element (element_1.stiffness, ...) and internal_step_s. Any
    communication step works: the coupling steps through it with equal steps of at most the
    internal step. The FMU is built with pythonfmu and runs the coupling in Python: the importing
    tool needs a Python 3 with pythonfmu and droptower installed (see the README).

    \b
    Examples:
      droptower export-fmu rapp2022_nr60 --out nr60.fmu
      droptower export-fmu identified.toml --out identified.fmu --internal-step-s 1e-5
    """
    from droptower.fmu import build_fmu
    from droptower.rheology.loader import load_coupling

    if not (0 < internal_step_s <= 1.0):  # also refuses nan
        raise DroptowerError(f"--internal-step-s must be > 0 and at most 1, got {internal_step_s:g}")
    path = build_fmu(load_coupling(coupling), out, internal_step_s)
    click.echo(f"FMU: {path}")
