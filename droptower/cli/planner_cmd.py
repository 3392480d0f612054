"""``droptower planner``: the interactive planner page (one offline HTML file)."""
from __future__ import annotations

import click

from droptower.cli.design_cmd import _preloads
from droptower.cli.options import note, quiet_option
from droptower.configs import DEFAULT_COUPLING, DEFAULT_RIG
from droptower.errors import DroptowerError


#: the planner page's advice on running a saved plan, as a shell command
RUN_HINT = "droptower campaign --doe plan.toml --out runs/designed"


@click.command()
@quiet_option
@click.option("--out", required=True, type=click.Path(dir_okay=False), help="The page to write (.html).")
@click.option("--rig", default=DEFAULT_RIG, show_default=True, help="Rig TOML file or shipped preset name.")
@click.option("--coupling", default=DEFAULT_COUPLING, show_default=True,
              help="Coupling TOML file or shipped preset name (what the drops are predicted on).")
@click.option("--preloads-nm", default="0", show_default=True,
              help="Preloads the page offers and every designed condition is tested at (N*m), comma-separated.")
def planner(out: str, rig: str, coupling: str, preloads_nm: str) -> None:
    """Write the lab's planner page: one self-contained HTML file (plotly embedded, opens offline).

    Pick a lever, drop mass, height and preload and see the predicted amplitude, frequency,
    damping, peak torque, impact force and double-impact margin; drag a target region on the
    amplitude-frequency plane (or type it) and see the conditions `droptower design` chooses for
    it, and download the plan TOML (the same plan `droptower design --out` writes; `droptower
    campaign --doe` runs it). The predictions are `droptower plan`'s, computed here on a grid of
    heights for every lever, mass and preload and interpolated in the browser.

    \b
    Examples:
      droptower planner --out planner.html
      droptower planner --out planner.html --preloads-nm 0,500,1000 --coupling my_coupling.toml
    """
    from pathlib import Path

    from droptower.planner import write_planner
    from droptower.planner.grid import check_preloads
    from droptower.rheology import load_coupling
    from droptower.rig.config import load_rig

    if Path(out).suffix.lower() not in (".html", ".htm"):
        raise DroptowerError("the planner is an HTML page: give a name ending in .html", file=out, where="--out")
    rig_cfg, model, preloads = load_rig(rig), load_coupling(coupling), _preloads(preloads_nm)
    check_preloads(rig_cfg, preloads)
    note(f"predicting every drop of rig {rig_cfg.name} with {model.name}")
    click.echo(f"planner: {write_planner(rig_cfg, model, preloads, out, run_hint=RUN_HINT)}")
