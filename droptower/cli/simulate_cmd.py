"""``droptower simulate``: one drop test on the virtual drop tower -> figures, log, plot."""
from __future__ import annotations

import json

import click

from droptower.cli.options import quiet_option, renamed_option, wrote
from droptower.configs import DEFAULT_COUPLING, DEFAULT_RIG
from droptower.jsonsafe import json_safe


@click.command()
@quiet_option
@click.option("--rig", default=DEFAULT_RIG, show_default=True, help="Rig TOML file or shipped preset name.")
@click.option("--coupling", default=DEFAULT_COUPLING, show_default=True,
              help="Coupling TOML file or shipped preset name.")
@renamed_option("--inertia-kgm2", "--inertia", "inertia", type=float, required=True,
                help="Lever inertia J about the axis (kg*m^2). [required]")
@renamed_option("--drop-mass-kg", "--drop-mass", "drop_mass", type=float, required=True,
                help="Drop mass m1 (kg). [required]")
@renamed_option("--height-m", "--height", "height", type=float, required=True,
                help="Drop height h above the impact point (m). [required]")
@click.option("--preload-nm", type=float, default=0.0, show_default=True, help="Preload torque (N*m).")
@click.option("--duration-s", type=float, default=0.25, show_default=True,
              help="Record length after the impact (s); the record starts the rig's pre-trigger before it.")
@click.option("--seed", type=int, default=0, show_default=True, help="Seed of the sensor noise.")
@click.option("--out", type=click.Path(dir_okay=False), default=None,
              help="Write the sampled test as a droptower log (.csv or .parquet).")
@click.option("--json", "as_json", is_flag=True, help="Print the results as one JSON object.")
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False), default=None,
              help="Draw the paths of drop mass and lever tip (Rapp et al. 2022, Fig. 4) and the angle and torque.")
def simulate(rig: str, coupling: str, inertia: float, drop_mass: float, height: float, preload_nm: float,
             duration_s: float, seed: int, out: str | None, as_json: bool, plot_path: str | None) -> None:
    """Simulate one drop test: the drop mass falls from HEIGHT onto the lever (inertia J) and the
    coupling, pre-twisted to the preload, rings down. Prints the post-impact velocities (simulated
    and by the impact law), impact energy, contacts and double impact, peak angle and torque, and
    the energy balance; writes the log the rig's sensors would record. A double impact is a
    second contact within the lever's first oscillation period (Rapp et al. 2022, docs/theory.md#decay).

    \b
    Examples:
      droptower simulate --inertia-kgm2 0.359 --drop-mass-kg 2 --height-m 1.0 --plot test.png
      droptower simulate --inertia-kgm2 0.1557 --drop-mass-kg 2 --height-m 0.4 --preload-nm 500 \\
          --out test.parquet --json
    """
    from droptower.errors import check_positive
    from droptower.rheology import load_coupling
    from droptower.rig.config import load_rig
    from droptower.rig.simulate import DropTest, check_size, simulate as run

    check_positive(duration_s, "--duration-s")
    rig_cfg = load_rig(rig)
    model = load_coupling(coupling)
    check_size(rig_cfg, model, 1, duration_s, where="--duration-s")
    rig_cfg.check_test(inertia, drop_mass, height, preload_nm,
                       labels={"inertia_kgm2": "--inertia-kgm2", "drop_mass_kg": "--drop-mass-kg", "drop_height_m": "--height-m",
                               "preload_nm": "--preload-nm"})
    result = run(rig_cfg, model, [DropTest(inertia, drop_mass, height, preload_nm, 0, seed)], duration_s)[0]
    summary = result.to_dict()
    if out:
        summary["log"] = str(result.write_log(out))
        wrote(summary["log"], "the test as the rig's sensors record it")
    if plot_path:
        from droptower.rig.plots import plot_test

        summary["plot"] = str(plot_test(result, plot_path))
        wrote(summary["plot"], "drop mass and lever paths (Rapp et al. 2022, Fig. 4), angle and torque")
    if as_json:
        click.echo(json.dumps(json_safe(summary), indent=1))
        return
    s = summary
    click.echo("\n".join(line for line in result.summary().splitlines() if not line.startswith("warning: ")))
    for w in s["warnings"]:
        click.echo(f"droptower: warning: {w}", err=True)
