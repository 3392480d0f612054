"""``droptower plan``: predict a test plan on a rig before running it."""
from __future__ import annotations

import json

import click

from droptower.cli.options import quiet_option, wrote
from droptower.configs import DEFAULT_COUPLING, DEFAULT_DOE, DEFAULT_RIG
from droptower.jsonsafe import json_safe

#: Columns printed as the table (all are in --out and --json).
TABLE_COLUMNS = ["case", "inertia_kgm2", "drop_mass_kg", "drop_height_m", "preload_nm", "repeats",
                 "lever_rate_after_rad_per_s", "impact_energy_j", "amplitude_deg", "max_twist_deg",
                 "first_period_frequency_hz",
                 "damping_ratio", "peak_torque_nm", "double_impact", "min_clearance_mm", "warnings"]


@click.command()
@quiet_option
@click.option("--rig", default=DEFAULT_RIG, show_default=True, help="Rig TOML file or shipped preset name.")
@click.option("--coupling", default=DEFAULT_COUPLING, show_default=True,
              help="Coupling TOML file or shipped preset name.")
@click.option("--doe", default=DEFAULT_DOE, show_default=True, help="Test-plan TOML file or shipped preset name.")
@click.option("--duration-s", type=float, default=0.25, show_default=True,
              help="Record length after the impact (s), for the 3/4-period check.")
@click.option("--out", type=click.Path(dir_okay=False), default=None,
              help="Write the full table to this file (.csv, .parquet, .json or .xlsx).")
@click.option("--json", "as_json", is_flag=True, help="Print the table as a JSON list of objects.")
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False), default=None,
              help="Draw twist, frequency, peak torque and double-impact clearance over drop height.")
def plan(rig: str, coupling: str, doe: str, duration_s: float, out: str | None, as_json: bool,
         plot_path: str | None) -> None:
    """Predict every condition of a test plan (repeats collapsed): post-impact velocities and
    impact energy (docs/theory.md#impact), angle amplitude, frequency, damping ratio and peak torque from a
    free decay on the nonlinear coupling (preload included), and the double-impact check of
    Rapp et al. 2022 (docs/theory.md#decay). Warns where a rig limit is broken: twist beyond the coupling limit,
    torque or impact force beyond the sensor range, fewer than 20 samples per period, a record
    shorter than 3/4 period, a double impact.

    \b
    Examples:
      droptower plan --plot plan.png
      droptower plan --doe my_plan.toml --coupling my_coupling.toml --out plan.xlsx
    """
    import pandas as pd

    from droptower.errors import check_positive
    from droptower.io.tables import check_table_path, write_table
    from droptower.rheology import load_coupling
    from droptower.rig.config import load_doe, load_rig
    from droptower.rig.predictions import plan as predict

    check_positive(duration_s, "--duration-s")
    if out:
        check_table_path(out, "--out")
    rig_cfg = load_rig(rig)
    model = load_coupling(coupling)
    plan_cfg = load_doe(doe)
    plan_cfg.check(rig_cfg)
    table = predict(rig_cfg, model, plan_cfg.conditions(), duration_s)
    if out:
        wrote(write_table(table, out, "--out"), f"{len(table)} condition(s)")
    if plot_path:
        from droptower.rig.plots import plot_plan

        wrote(plot_plan(table, rig_cfg, plot_path, model.name), "twist, frequency, peak torque, clearance over height")
    if as_json:
        click.echo(json.dumps(json_safe(table.to_dict(orient="records")), indent=1))
        return
    click.echo(f"{plan_cfg.name}: {len(table)} conditions, {int(table['repeats'].sum())} tests; "
               f"{model.name} on {rig_cfg.name}")
    with pd.option_context("display.width", 250, "display.max_columns", 40, "display.max_colwidth", 80,
                           "display.float_format", "{:.4g}".format):
        shown = table[[c for c in TABLE_COLUMNS if c in table]].assign(warnings=table["warnings"].map("; ".join))
        click.echo(shown.to_string(index=False))
    n_double = int(table["double_impact"].sum())
    n_warn = int((table["warnings"].map(len) > 0).sum())
    click.echo(f"{n_double} condition(s) double-impact, {n_warn} with warnings")
