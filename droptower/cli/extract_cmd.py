"""``droptower extract PATH...``: stiffness and damping of drop tests from their logs
(Rapp et al. 2022, Fig. 9, eq. 13-18; docs/theory.md#extraction, #damping-measures)."""
from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import click

from droptower.cli.options import (conditions_from_cli, conditions_options, note, note_uncertainty, progress_disabled,
                                   quiet_option, renamed_option, rig_for_logs, uncertainty_from_cli, uncertainty_option,
                                   wrote)
from droptower.errors import DroptowerError, WriteError, check_positive, make_folder
from droptower.cli.flags import cli_message, cli_text

#: columns of the table printed when neither --out nor --json is given
SUMMARY = ("file", "drop_index", "t_impact_s", "frequency_hz", "amplitude_deg", "stiffness_nm_per_deg",
           "damping_ratio", "lehr_damping", "stiffness_torque_nm_per_deg", "loss_factor", "relative_damping_psi", "fit_error", "flags")


#: added to :data:`SUMMARY` when the rows carry input uncertainties
SUMMARY_U95 = ("stiffness_nm_per_deg_U95", "stiffness_nm_per_deg_dominant", "loss_factor_U95")


def _summary(rows: list[dict[str, Any]]) -> str:
    columns = SUMMARY + (SUMMARY_U95 if any(SUMMARY_U95[0] in r for r in rows) else ())
    def cell(v: Any) -> str:
        if isinstance(v, float):
            return f"{v:.4g}"
        if isinstance(v, list):
            return ";".join(v) or "-"
        return str(v)

    table = [[cell(r.get(c, "")) for c in columns] for r in rows]
    widths = [max(len(h), *(len(r[i]) for r in table)) for i, h in enumerate(columns)]
    return "\n".join("  ".join(v.ljust(w) for v, w in zip(line, widths)) for line in [list(columns), *table])


def _uncertainty_rows(drops: list[tuple[int, str, Any]], uncertainty: Any, rig: Any, method: str,
                      lever_length_m: float | None, laser_radius_m: float | None) -> list[dict[str, Any]]:
    """Each drop's uncertainty columns. ``auto``: the campaign's route (Monte Carlo on the drops
    whose budget's make-up no earlier drop had, :func:`droptower.uncertainty.campaign_budgets`);
    a drop whose budget cannot be made (a nominal value its log lacks) gets empty columns and a
    warning, its results stand."""
    from droptower.uncertainty import campaign_budgets, drop_budget, uncertainty_columns

    nominal = {"lever_length_m": lever_length_m, "laser_radius_m": laser_radius_m}
    metas = [{**drop.signals.metadata, **{k: v for k, v in nominal.items() if v is not None}} for _, _, drop in drops]
    if method == "auto":
        try:
            keys = [tuple(m.get(k) for k in ("inertia_kgm2", "drop_mass_kg", "drop_height_m", "preload_nm"))
                    for m in metas]
            budgets = campaign_budgets([d.result for _, _, d in drops], uncertainty, conditions=keys, metadata=metas,
                                       rig=rig)
            return [uncertainty_columns(b) for b in budgets]
        except DroptowerError:
            pass  # one drop's problem: each drop on its own below, the failing ones named
    out = []
    for (_, path, drop), meta in zip(drops, metas):
        try:
            budget = drop_budget(drop.result, uncertainty, rig=rig, metadata=meta, method=method, seed=drop.span.index)
        except DroptowerError as exc:
            click.echo(f"droptower: warning: {path}: no uncertainty budget: {cli_message(exc)}", err=True)
            budget = None
        out.append(uncertainty_columns(budget))
    return out


@click.command()
@quiet_option
# readable=False: an unreadable file is reported by the reader and the batch goes on
@click.argument("paths", nargs=-1, required=True, type=click.Path(path_type=str, readable=False))
@click.option("--rig", default=None, help="Rig TOML (or shipped preset name): lever length, laser radius, fixtures "
              "(the inertia of a rig with one fixture; with several, --conditions or the logs say which). Make "
              "your own with `droptower rig new`.")
@conditions_options
@renamed_option("--inertia-kgm2", "--inertia", "inertia", type=float,
                help="Rotating inertia J in kg*m^2 (default: the log's metadata).")
@renamed_option("--lever-length-m", "--lever-length", "lever_length", type=float,
                help="Lever arm L in m (rotation axis to impact point).")
@renamed_option("--sensor-radius-m", "--sensor-radius", "sensor_radius", type=float,
                help="Laser spot radius in m, for a distance channel (default: the log's metadata).")
@click.option("--channel", "channel_specs", multiple=True, metavar="ROLE=NAME[:UNIT]",
              help="Map a channel to a role: time, impact_force, angle, distance, torque (repeatable).")
@renamed_option("--sample-rate-hz", "--sample-rate", "sample_rate", type=float,
                help="Sample rate in Hz for files without a time base.")
@click.option("--window", default="first-cycle", show_default=True,
              help="Fit window after the impact: first-cycle, N-cycles (e.g. 2-cycles) or seconds (e.g. 0.05).")
@click.option("--drops", "drop_selection", default=None, metavar="1,3-5",
              help="Evaluate only these drops of each recording (numbered from 1 in time order; default: all).")
@click.option("--drop-conditions", type=click.Path(dir_okay=False, path_type=str), default=None,
              help="Table (CSV, .xlsx, .parquet) drop_index,drop_height_m,drop_mass_kg,inertia_kgm2,preload_nm "
                   "(any of them): the conditions of each drop of a recording holding several, by its number; over "
                   "the log's metadata and --conditions (which are per file).")
@click.option("--pre-trigger-s", type=float, default=0.005, show_default=True,
              help="Pre-trigger baseline of each drop in a recording with several drops, in s.")
@click.option("--min-drop-spacing-s", type=float, default=0.5, show_default=True,
              help="Shortest time between two drops' impacts in s: impacts sooner are later contacts of the "
                   "same drop.")
@click.option("--out", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Write the results table to this file (.csv, .parquet, .json or .xlsx).")
@click.option("--json", "as_json", is_flag=True, help="Print the results as a JSON list of objects.")
@click.option("--plot", "plot_dir", type=click.Path(file_okay=False, path_type=Path), default=None,
              help="Draw per test the angle and torque with their fits (Rapp et al. 2022, Fig. 9) into this folder.")
@uncertainty_option
@click.option("--uncertainty-method", type=click.Choice(["auto", "gum", "mc"]), default="auto", show_default=True,
              help="With input uncertainties: auto (the GUM where Monte Carlo validates it, else Monte Carlo; "
                   "JCGM 101, 8; Monte Carlo run once per make-up of the budget, not per drop), gum (first order "
                   "only, fast) or mc (Monte Carlo on every drop).")
@click.option("--delimiter", default=None, help="CSV field separator (default: sniffed).")
@click.option("--decimal", type=click.Choice([".", ","]), default=None, help="CSV decimal separator (default: sniffed).")
@click.option("--header-lines", type=int, default=None, help="CSV lines above the names row (default: sniffed).")
@click.option("--unit-row/--no-unit-row", default=None, help="CSV has a units row under the names (default: sniffed).")
def extract(paths: tuple[str, ...], rig: str | None, conditions: str | None, condition_columns: tuple[str, ...],
            conditions_pattern: str | None, inertia: float | None, lever_length: float | None,
            sensor_radius: float | None, channel_specs: tuple[str, ...], sample_rate: float | None, window: str,
            drop_selection: str | None, drop_conditions: str | None, pre_trigger_s: float, min_drop_spacing_s: float,
            out: Path | None, as_json: bool, plot_dir: Path | None, uncertainty_specs: tuple[str, ...],
            uncertainty_method: str, delimiter: str | None, decimal: str | None, header_lines: int | None,
            unit_row: bool | None) -> None:
    """Extract stiffness and damping from drop-test logs PATH... (any number, any format).

    Per test: impact and pre-trigger baseline (offsets, preload), least-squares fit of
    φ̂·e^(−δt)·cos(ωt − Φ) over the window, c_dyn,M1 = J(ω² + δ²), damping_ratio = Rapp's d = E_diss/E_el = ½(e^(4πδ/ω) − 1) beside Lehr's D (lehr_damping),
    φ̂_ref, f (Rapp et al. 2022, eq. 13-18); the torque fit (eq. 17) and c_dyn,M2; the servo-comparable
    loss factor η and relative damping ψ (docs/theory.md#damping-measures); standard uncertainties (*_std), the fit
    error and flags (double_impact, clipping, too_few_samples_per_period, short_window,
    poor_fit) and the geometry cross-checks (stiffness_m2_m1_deviation, laser_torque_amplitude_mismatch,
    impact_energy_mismatch: a wrong laser radius, lever length or fixture). J, L and the laser
    radius: --inertia-kgm2/--lever-length-m/--sensor-radius-m, else --conditions (per file: a
    sheet keyed by file name, or --conditions-from-names), else the log's metadata, else --rig
    (its inertia only if it has a single lever fixture). The geometry used is printed once and
    written with every row (rig, lever_length_m, sensor_radius_m), with the fixture and
    temperature_c.

    A file the conditions table lacks fails on its own; bad rows of the table are warned about
    once and fail only their files. --drop-conditions is for recordings of several drops: keyed
    by the drop's number, over --conditions.

    Input uncertainties (the rig file's [uncertainty] table, --uncertainty over it): each row
    gains <output>_u (combined standard uncertainty), <output>_U95 (expanded, 95 %: k = 2, or
    the Monte Carlo interval's half-width) and <output>_dominant (the budget's largest term: an
    input or the fit), and uncertainty_not_given (inputs left out, never counted as zero); the
    inputs' share is propagated through the extraction's own equations (GUM, JCGM 100; Monte
    Carlo, JCGM 101; docs/guide/uncertainty.md). None given: the fit's *_std only, and a note says so.

    Time stamps printed with few decimals (steps that differ only by the printed precision)
    are taken as a constant sample rate estimated from the whole log (a note says so); a truly
    irregular time base is refused.

    A recording may hold several drops (a series recorded continuously): each impact (a force
    pulse, or without a force channel the angle leaving rest) is one drop with its own
    pre-trigger baseline, fit window and double-impact check, and one result row (drop_index,
    t_impact_s on the log's clock). A drop whose oscillation is still running when the next
    impact comes is flagged decay_cut_by_next_drop.

    A file that fails is reported on one line; the others are still evaluated and written, the
    failures are listed at the end and the exit code is 2 (a user error, as for a single file).

    \b
    Examples:
      droptower extract logs/*.csv --out results.xlsx
      droptower extract drop_017.bin --channel angle=Winkel:deg --channel torque=Md:kN*m \\
          --inertia-kgm2 0.359 --lever-length-m 0.2 --json
      droptower extract logs/*.parquet --rig rapp2022 --window 2-cycles --plot plots/
      droptower extract morning.mf4 --drops 1,3-5 --drop-conditions drops.csv --out morning.csv
      droptower extract lab/*.csv --rig lab_rig.toml --conditions lab/conditions.xlsx --out results.csv
      droptower extract lab/*.csv --rig lab_rig.toml \\
          --conditions-from-names '{fixture}_m{drop_mass_kg}_h{drop_height_mm}_rep{repeat}'
    """
    import pandas as pd
    from tqdm import tqdm

    from droptower.extract.drop_spans import parse_drop_selection, read_drop_conditions
    from droptower.extract.files import Settings, extract_drops, result_row
    from droptower.jsonsafe import json_safe
    from droptower.extract.window import Window
    from droptower.io.tables import check_table_path, write_table
    from droptower.io.mapping import parse_channel_options

    if out is not None:
        check_table_path(out, "--out")
    for name, value, most in (("--inertia-kgm2", inertia, 1e3), ("--lever-length-m", lever_length, 10.0),
                              ("--sensor-radius-m", sensor_radius, 10.0), ("--sample-rate-hz", sample_rate, 1e9)):
        check_positive(value, name, most=most)
    for name, value in (("--pre-trigger-s", pre_trigger_s), ("--min-drop-spacing-s", min_drop_spacing_s)):
        check_positive(value, name, most=3600.0)
    rig_config = rig_for_logs(rig, paths)
    input_u = uncertainty_from_cli(uncertainty_specs, rig_config)
    table = conditions_from_cli(conditions, condition_columns, conditions_pattern, rig_config)
    settings = Settings(
        roles=parse_channel_options(channel_specs), inertia_kgm2=inertia, lever_length_m=lever_length,
        rig=rig_config, conditions=table, sensor_radius_m=sensor_radius,
        sample_rate_hz=sample_rate, window=Window.parse(window),
        reader_options={"delimiter": "\t" if delimiter == "\\t" else delimiter, "decimal": decimal,
                        "header_lines": header_lines, "unit_row": unit_row},
        drops=frozenset(parse_drop_selection(drop_selection)) if drop_selection is not None else None,
        drop_conditions=read_drop_conditions(drop_conditions) if drop_conditions is not None else {},
        pre_trigger_s=pre_trigger_s, min_drop_spacing_s=min_drop_spacing_s,
    )
    if plot_dir is not None:  # the output place first: a folder that cannot be made is its own error
        from droptower.extract.plot import plot_fit

        make_folder(plot_dir)

    rows: list[dict[str, Any]] = []
    budget_drops: list[tuple[int, str, Any]] = []
    failures: list[str] = []
    failed: set[str] = set()
    plots: set[str] = set()
    shared = table.shared_rows(paths) if table is not None else {}
    for path in tqdm(paths, desc="extract", unit="log", file=sys.stderr, disable=progress_disabled()):
        try:
            if path in shared:  # one row for several logs: which one it means is not known
                raise DroptowerError(shared[path], file=path)
            for drop in extract_drops(path, settings):
                for text in drop.signals.notes if drop.span.index == 1 and not progress_disabled() else ():
                    tqdm.write(f"droptower: note: {path}: {text}", file=sys.stderr)
                if drop.error is not None:
                    failed.add(path)
                    failures.append(cli_message(drop.error))
                    tqdm.write(f"droptower: error: {failures[-1]}", file=sys.stderr)
                    continue
                if plot_dir is not None:
                    stem = Path(path).stem if drop.drops_in_file == 1 else f"{Path(path).stem}_drop{drop.span.index}"
                    name = stem if stem not in plots else f"{stem}_{len(plots)}"
                    plots.add(name)
                    plot_fit(drop.signals, drop.result, plot_dir / f"{name}.png", title=None)
                rows.append(result_row(path, drop.signals, drop.result, drop.span.index))
                if input_u is not None:
                    budget_drops.append((len(rows) - 1, path, drop))
        except WriteError:  # the output place, not this log: the next plot would fail alike
            raise
        except DroptowerError as exc:
            failed.add(path)
            failures.append(cli_message(exc.with_file(path)))
            tqdm.write(f"droptower: error: {failures[-1]}", file=sys.stderr)
        except Exception as exc:  # a bug must not stop a 450-file batch; name it and go on
            failed.add(path)
            failures.append(f"{path}: internal error ({type(exc).__name__}: {exc})")
            tqdm.write(f"droptower: error: {failures[-1]}", file=sys.stderr)

    if budget_drops:
        for i, columns in enumerate(_uncertainty_rows(budget_drops, input_u, rig_config, uncertainty_method,
                                                      lever_length, sensor_radius)):
            rows[budget_drops[i][0]].update(columns)
    if rows:  # a fixture or condition none of whose drops is usable is named, with why (as map names it)
        from droptower.maps.coverage import coverage_notes
        from droptower.maps.results import select_tests

        evaluated = pd.DataFrame(rows)
        for line in coverage_notes(evaluated, *select_tests(evaluated), rig=settings.rig):
            click.echo(f"droptower: warning: {cli_text(line)}", err=True)
    unused = table.unmatched(paths) if table is not None else []
    if unused:
        shown = ", ".join(unused[:5]) + (f" and {len(unused) - 5} more" if len(unused) > 5 else "")
        note(f"note: {len(unused)} row(s) of the conditions table {table.source} name no given log: {shown}")
    if rows and out is not None:
        table = pd.DataFrame(rows)
        wrote(write_table(table, out, "--out"), f"{len(table)} test(s) x {table.shape[1]} columns")
    if plots:
        wrote(plot_dir, f"{len(plots)} decay-fit plot(s)")
    if as_json:
        click.echo(json.dumps(json_safe(rows), indent=2))
    elif out is None and rows:
        click.echo(_summary(rows))
    if rows:  # after the results: what their uncertainties hold
        note_uncertainty(input_u)
    if failures and (len(paths) > 1 or rows):  # one file, one failure: its error line above says it all
        click.echo(f"droptower: {len(failed)} of {len(paths)} file(s) failed:", err=True)
        for line in failures:
            click.echo(f"  {line}", err=True)
    if failures:
        raise click.exceptions.Exit(2)
