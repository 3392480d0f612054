"""``droptower servo``: drive a coupling on the virtual servo-hydraulic bench over a grid."""
from __future__ import annotations

import json
import math

import click

from droptower.cli.options import note, quiet_option, wrote
from droptower.errors import DroptowerError, check_positive
from droptower.jsonsafe import json_safe
from droptower.rates import RIG_SAMPLE_RATE_HZ, SERVO_SAMPLE_RATE_HZ
from droptower.rig.config import PRELOAD_HOLD_S

#: Columns of the default table (all are in the JSON output).
TABLE_COLUMNS = ["amplitude_deg", "frequency_hz", "preload_nm", "offset_deg", "storage_stiffness_nm_per_rad",
                 "loss_stiffness_nm_per_rad", "dynamic_stiffness_nm_per_deg", "loss_factor", "loss_angle_deg",
                 "damping_work_j", "relative_damping_psi", "drop_tower_equivalent_damping_ratio"]
#: A grid point whose single cycles differ by more than this is reported as not steady.
STEADY_WARNING = 0.02


def _float_list(option: str, text: str) -> list[float]:
    """``"0.5,1.5"`` -> [0.5, 1.5]; anything else is a one-line error naming the option."""
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        raise DroptowerError(f"expected comma-separated numbers, got {text!r}", where=option) from None
    for value in values:
        check_positive(value, option)
    return values


@click.command()
@quiet_option
@click.argument("coupling")
@click.option("--amplitude-deg", default="0.5,1.5", show_default=True, help="Amplitudes (deg), comma-separated.")
@click.option("--frequency-hz", default="1,10,30", show_default=True, help="Frequencies (Hz), comma-separated.")
@click.option("--preload-nm", default=0.0, show_default=True, type=float, help="Mean torque (N*m) to oscillate about.")
@click.option("--amplitude-mm", default=None,
              help="Translational coupling: amplitudes (mm), comma-separated [default: 0.1,0.5].")
@click.option("--preload-n", default=None, type=float, help="Translational coupling: mean force (N) [default: 0].")
@click.option("--preload-hold-s", default=PRELOAD_HOLD_S, show_default=True, type=float,
              help="With a preload: how long the mean angle is held, after a quasi-static ramp, before the sine.")
@click.option("--sample-rate-hz", default=SERVO_SAMPLE_RATE_HZ, show_default=True, type=float,
              help="Acquisition rate of the evaluated record (default: the paper's bench).")
@click.option("--simulation-rate-hz", default=RIG_SAMPLE_RATE_HZ, show_default=True, type=float,
              help="Least rate the coupling is simulated at (raised to 4096 steps per cycle, "
                   "rounded up to a multiple of the sample rate).")
@click.option("--cycles", default=5, show_default=True, type=click.IntRange(min=1), help="Evaluated cycles.")
@click.option("--run-in-cycles", default=5, show_default=True, type=click.IntRange(min=1),
              help="Discarded cycles before them (the amplitude rises over the first two).")
@click.option("--no-smoothing", is_flag=True,
              help="Skip the one-eighth-cycle Savitzky-Golay smoothing (it rounds hard loop corners).")
@click.option("--json", "as_json", is_flag=True, help="Print a JSON list of objects instead of a table.")
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False), help="Write the hysteresis loops to this image.")
def servo(coupling: str, amplitude_deg: str, frequency_hz: str, preload_nm: float, amplitude_mm: str | None,
          preload_n: float | None, preload_hold_s: float, sample_rate_hz: float, simulation_rate_hz: float, cycles: int, run_in_cycles: int,
          no_smoothing: bool, as_json: bool, plot_path: str | None) -> None:
    """Drive COUPLING (a coupling TOML file or a preset name) with sine tests on the virtual
    servo-hydraulic bench and evaluate each like a test lab: K', K'', |K*|, loss angle, loss
    factor, damping work (loop area), relative damping psi (DIN 740-2 style) and the
    drop-tower-equivalent damping ratio (docs/theory.md#damping-measures).

    A translational coupling (units = "translational": a mount, bushing or damper) is driven
    by displacement: --amplitude-mm and --preload-n instead of --amplitude-deg and
    --preload-nm, and the table's fields are named for it (storage_stiffness_n_per_m,
    amplitude_mm, ...).

    \b
    Examples:
      droptower servo rapp2022_nr60 --amplitude-deg 0.5,1.5 --frequency-hz 1,10,30 --plot loops.png
      droptower servo my_coupling.toml --preload-nm 500 --json > servo.json
      droptower servo seed002_bushing --amplitude-mm 0.1,1 --frequency-hz 1,10,50
    """
    from droptower.rheology import load_coupling
    from droptower.servo import run_bench

    from droptower.io.fields import field_name, translate_table

    freqs = _float_list("--frequency-hz", frequency_hz)
    model = load_coupling(coupling)
    translational = model.units == "translational"
    given = click.get_current_context().get_parameter_source
    torsional_given = [o for o, p in (("--amplitude-deg", "amplitude_deg"), ("--preload-nm", "preload_nm"))
                       if given(p) != click.core.ParameterSource.DEFAULT]
    translational_given = [o for o, v in (("--amplitude-mm", amplitude_mm), ("--preload-n", preload_n)) if v is not None]
    if translational and torsional_given:
        raise DroptowerError(f"{model.name} is a translational coupling: give --amplitude-mm and --preload-n, "
                             f"not {' and '.join(torsional_given)}")
    if not translational and translational_given:
        raise DroptowerError(f"{model.name} is a torsional coupling: {' and '.join(translational_given)} "
                             f"{'are' if len(translational_given) > 1 else 'is'} for translational ones "
                             "(give --amplitude-deg and --preload-nm)")
    if translational:  # the same numbers read as m and N
        amps_si = [1e-3 * a for a in _float_list("--amplitude-mm", amplitude_mm or "0.1,0.5")]
        preload_nm = preload_n or 0.0
    else:
        amps_si = [math.radians(a) for a in _float_list("--amplitude-deg", amplitude_deg)]
    result = run_bench(model, amps_si, freqs, preload_nm, sample_rate_hz, cycles,
                       run_in_cycles=run_in_cycles, ramp_cycles=min(2, run_in_cycles),
                       simulation_rate_hz=simulation_rate_hz, smooth=not no_smoothing, preload_hold_s=preload_hold_s)
    table = translate_table(result.table, model.units)
    amplitude = field_name("amplitude_deg", model.units)
    for _, row in table.iterrows():
        if row["steady_state_deviation"] > STEADY_WARNING:
            click.echo(f"droptower: warning: {row[amplitude]:.6g} {amplitude.rsplit('_', 1)[1]}, "
                       f"{row['frequency_hz']:g} Hz: single cycles "
                       f"differ by {100 * row['steady_state_deviation']:.1f} % (not steady, or the record is coarse "
                       f"for this loop); raise --run-in-cycles or --sample-rate-hz", err=True)
    unsmoothed = table.loc[table["smoothing_window_samples"] == 0, "frequency_hz"].unique()
    if unsmoothed.size and not no_smoothing:
        note(f"note: no smoothing at {', '.join(f'{f:g}' for f in unsmoothed)} Hz (one eighth of a "
             f"cycle is fewer than 5 samples at {sample_rate_hz:g} Hz)")
    if as_json:
        click.echo(json.dumps(json_safe(table.to_dict(orient="records")), indent=1))
    else:
        click.echo(f"{model.name}: servo bench, sampled at {sample_rate_hz:g} Hz, "
                   f"simulated at {table['simulation_rate_hz'].min():g} to {table['simulation_rate_hz'].max():g} Hz, "
                   f"{run_in_cycles} run-in and {cycles} evaluated cycles")
        click.echo(table[[field_name(c, model.units) for c in TABLE_COLUMNS]].to_string(
            index=False, float_format=lambda v: f"{v:.5g}"))
    if plot_path:
        from droptower.servo.plots import plot_loops

        plot_loops(result, plot_path, units=model.units, title=f"{model.name}: hysteresis loops, preload "
                                                               f"{preload_nm:g} {'N' if translational else 'N*m'}")
        wrote(plot_path, "hysteresis loops")
