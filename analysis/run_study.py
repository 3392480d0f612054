"""The study of Rapp et al. 2022, end to end, on the virtual rig: campaign -> map -> servo validation ->
comparison with the paper's measured map (Table 4), into one report folder.

    python analysis/run_study.py [--out report] [--reduced] [--coupling rapp2022_nr60] [--workers N]

1. the Table-2 campaign (450 tests; ``--reduced``: one repeat of five drop heights per case,
   no preload: 15 tests) on the rig ``rapp2022`` with the coupling (default the calibrated
   ``rapp2022_nr60``): simulated, logged, extracted from the logs (``droptower campaign``),
   into ``OUT/campaign/`` (resumed if it is there already);
2. the characteristic map, Rapp et al. 2022, eq. 19 and eq. 20 (``droptower map``): ``OUT/map.json``
   and Fig. 10, 12, 13;
3. the servo-hydraulic validation, docs/theory.md#servo sweeps on the virtual servo bench
   (``droptower validate``; ``--reduced``: fewer steps): ``OUT/validation.csv``, Fig. 14;
4. the comparison with Table 4 (shipped: ``droptower/data/rapp2022_table4_map.csv``): per row the
   map at the row's amplitude and frequency and the campaign's tests interpolated at the row's
   case and amplitude: ``OUT/table4_comparison.csv``, printed with the acceptance (RMS <= 5 %
   stiffness, <= 12 % damping ratio); the map-free check (drop tests placed on the servo points
   inside the tested hull: ``OUT/map_free_check.csv``), the coupling's loss-factor ratio, third
   harmonic and speed, and the reference coupling's targets, each met or missed;
5. the map form chosen by cross-validation (``droptower map --form auto``) on Table 4 and on the
   campaign, its errors and time (not with ``--reduced``);
6. ``OUT/index.html`` with every table and figure, and ``OUT/summary.json`` (with the hashes of
   the presets and source files it came from: ``analysis/provenance.py``; no machine paths).
"""
from __future__ import annotations

import argparse
import html
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import tomli_w
from matplotlib.figure import Figure
from matplotlib.ticker import NullFormatter, ScalarFormatter

from droptower.campaign import run_campaign
from droptower.campaign.folder import write_json
from droptower.compare import compare_reference, compare_with_servo, format_comparison, format_summary, run_sweeps
from droptower.compare.files import write_csv, write_validation
from droptower.compare.mapfree import MapFreeCheck, format_check, run_check
from droptower.configs import DEFAULT_COUPLING, DEFAULT_DOE, DEFAULT_RIG, preset_dir, read_toml, resolve
from droptower.data import table4_path
from droptower.errors import DroptowerError
from droptower.maps import fit_map, select_tests
from droptower.maps.plots import plot_all
from droptower.rates import RIG_SAMPLE_RATE_HZ
from droptower.rheology import load_coupling
from droptower.rig.config import load_rig
from droptower.servo.steady import rubber_figures
from provenance import provenance  # analysis/provenance.py

REFERENCE = table4_path()  # Rapp et al. 2022, Table 4, shipped with the package
REDUCED_HEIGHTS_M = [0.05, 0.4, 1.0, 3.5, 6.0]
TABLE4_FIGURE = "table4_comparison.png"


def reduced_plan(folder: Path) -> Path:
    """The Table-2 plan cut to one repeat of a few heights, no preload (a test file in ``folder``)."""
    plan = read_toml(resolve(DEFAULT_DOE, "doe"))
    plan.update(name=f"{plan['name']}_reduced", description="Table 2 reduced for CI: five heights, one repeat, no preload",
                repeats=1, heights_m=REDUCED_HEIGHTS_M, preloads_nm=[0.0])
    path = folder / "reduced_plan.toml"
    folder.mkdir(parents=True, exist_ok=True)
    path.write_text(tomli_w.dumps(plan))
    return path


def plot_table4(comparison: pd.DataFrame, results: pd.DataFrame, path: Path) -> Path:
    """Stiffness and damping ratio over amplitude per case: Table 4, the campaign's tests, the
    campaign interpolated at Table 4's amplitudes and the map at Table 4's (amplitude, frequency)."""
    usable, _ = select_tests(results)
    fig = Figure(figsize=(11, 4.6), layout="constrained")
    axes = fig.subplots(1, 2)
    for i, (inertia, rows) in enumerate(comparison.groupby("inertia_kgm2")):
        color = f"C{i}"
        tests = usable[np.isclose(usable["inertia_kgm2"], inertia, rtol=1e-6)]
        rows = rows.sort_values("amplitude_deg")
        for ax, q in ((axes[0], "stiffness_nm_per_deg"), (axes[1], "damping_ratio")):
            ax.plot(tests["amplitude_deg"], tests[q], ".", color=color, alpha=0.3, ms=4)
            ax.plot(rows["amplitude_deg"], rows[q], "s", color=color, mfc="none", label=f"J = {inertia:g} kg·m²")
            ax.plot(rows["amplitude_deg"], rows[f"campaign_{q}"], "-", color=color)
            ax.plot(rows["amplitude_deg"], rows[f"map_{q}"], "x", color=color)
    axes[0].set(xlabel="angular amplitude [deg]", ylabel="stiffness [N·m/deg]", xscale="log")
    axes[1].set(xlabel="angular amplitude [deg]", ylabel="damping ratio d [-]", xscale="log")
    for ax in axes:
        ax.xaxis.set_major_formatter(ScalarFormatter())
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.set_xticks([0.1, 0.2, 0.5, 1, 2, 5])
        ax.grid(True, alpha=0.3, which="both")
        ax.legend(fontsize=8)
    fig.suptitle("Virtual campaign vs the paper's measured map (Rapp et al. 2022, Table 4). Squares: Table 4; lines: campaign "
                 "interpolated at its amplitudes;\ncrosses: map at Table 4's amplitude and frequency; dots: single tests",
                 fontsize=10)
    fig.savefig(path, dpi=110)
    return path


def _table_html(table: pd.DataFrame, digits: int = 4) -> str:
    return table.to_html(index=False, float_format=lambda v: f"{v:.{digits}g}", border=0, classes="data",
                         na_rep="")


def write_index(out: Path, facts: dict[str, Any], sections: list[tuple[str, str]]) -> Path:
    """``index.html``: the campaign's report (``droptower report``) followed by the study's
    facts and (heading, html) sections."""
    from droptower.report import write_report

    study = "<table class='data'>" + "".join(
        f"<tr><th>{html.escape(k)}</th><td style='text-align:left'>{html.escape(str(v))}</td></tr>"
        for k, v in facts.items()) + "</table>"
    return write_report(out / "campaign", out / "index.html", title="Drop-tower study of Rapp et al. 2022 on the virtual rig",
                        extra_sections=[("The study", study), *sections])


def by_preload_text(by_preload: dict[str, dict[str, Any]]) -> str:
    """The campaign's deviations from Table 4 per preload, one line each ('' for one preload)."""
    return "".join(f"\n    tests at preload {p} N*m only: stiffness rms {s['stiffness_rms_deviation_pct']:.2f} %, "
                   f"damping ratio rms {s['damping_rms_deviation_pct']:.2f} %" for p, s in by_preload.items())


def _pre(text: str) -> str:
    return f"<pre>{html.escape(text)}</pre>"


def _img(name: str) -> str:
    return f"<p><a href='{name}'><img src='{name}' alt='{name}'></a></p>"


def run_study(out: Path, reduced: bool = False, coupling: str = DEFAULT_COUPLING, workers: int | None = None,
              progress: bool = True) -> dict[str, Any]:
    """Run the study into ``out``; returns the summary (also written to ``out/summary.json``)."""
    if not REFERENCE.is_file():
        raise DroptowerError("Table 4 of Rapp et al. 2022 is needed for the comparison and is absent", file=REFERENCE)
    t0 = time.perf_counter()
    out.mkdir(parents=True, exist_ok=True)
    doe = reduced_plan(out) if reduced else DEFAULT_DOE

    # 1. campaign (resumed if the folder holds it already; another campaign there is an error)
    run = run_campaign(out / "campaign", DEFAULT_RIG, coupling, doe, workers=workers, resume=True, progress=progress)
    results = run.results
    t_campaign = time.perf_counter() - t0

    # 2. map
    # paths in stored results are relative (to the report folder, or the package's presets)
    fit = fit_map(results, source="campaign/results.parquet")
    fit.to_json(out / "map.json")
    usable, excluded = select_tests(results)
    map_figures, _ = plot_all(usable, fit, out)

    # 3. servo validation (docs/theory.md#servo, #damping-measures)
    points = run_sweeps(run.spec.coupling, reduced=reduced)
    validation = compare_with_servo(fit, points)
    write_validation(out, validation, fit, points)

    # 3b. map-free check: drop tests placed on the servo points inside the tested hull
    inside = validation.table[validation.table["in_range"]].drop_duplicates(["amplitude_deg", "frequency_hz"])
    coupling_model = load_coupling(run.spec.coupling.path)
    check = run_check(coupling_model, run.spec.coupling.path, run.spec.rig.path, load_rig(run.spec.rig.path),
                      inside, fit, out / "map_free_check", workers=workers, progress=progress) if len(inside) else None
    if check is not None:
        write_csv(out / "map_free_check.csv", check.table)
    rubber = {**rubber_figures(coupling_model), "real_time_factor": real_time_factor(coupling_model)}

    # 4. Table 4
    table4 = pd.read_csv(REFERENCE)
    comparison, comparison_summary = compare_reference(table4, fit, results)
    write_csv(out / "table4_comparison.csv", comparison)
    # the same per preload: the paper saw no influence of the preload (Rapp et al. 2022, Fig. 11)
    by_preload = {f"{p:g}": compare_reference(table4, None, results, p)[1]["campaign"]
                  for p in sorted(results["preload_nm"].unique())} if results["preload_nm"].nunique() > 1 else {}
    plot_table4(comparison, results, out / TABLE4_FIGURE)
    # 5. the map form chosen by cross-validation (droptower map --form auto): its errors and time
    auto = None if reduced else {"table4": auto_map(table4), "campaign": auto_map(results)}

    summary = {
        "reduced": reduced, "coupling": run.spec.coupling.name, "coupling_file": portable_path(run.spec.coupling.path),
        "rig": run.spec.rig.name, "plan": run.spec.doe.name, "tests": len(run.spec.tests),
        "tests_extracted": int((results["status"] == "done").sum()), "tests_failed": len(run.failed),
        "tests_pending": run.pending, "tests_excluded_from_map": len(excluded),
        "campaign_hashes": run.spec.hashes(), "record_duration_s": run.spec.duration_s,
        "map_fit": {k: v for k, v in fit.to_dict()["fit"].items()}, "map_range": fit.to_dict()["range"],
        "servo_validation": validation.summary, "map_free_check": check.summary if check is not None else None,
        "coupling_figures": rubber, "table4": comparison_summary, "table4_by_preload_nm": by_preload,
        "map_auto": auto, "campaign_wall_s": t_campaign, "study_wall_s": time.perf_counter() - t0,
        "provenance": provenance(*(run.spec.inputs[kind]["file"] for kind in ("rig", "coupling", "doe"))),
    }
    summary["targets"] = target_table(summary)
    write_json(out / "summary.json", summary)

    excluded_table = pd.DataFrame([{"test": e.test, "reason": e.reason} for e in excluded], columns=["test", "reason"])
    write_index(out, {
        "coupling": f"{run.spec.coupling.name} ({run.spec.coupling.path})", "rig": run.spec.rig.name,
        "plan": f"{run.spec.doe.name}: {len(run.spec.tests)} tests{' (reduced)' if reduced else ''}",
        "tests": f"{summary['tests_extracted']} extracted, {summary['tests_failed']} failed, "
                 f"{len(excluded)} excluded from the map",
        "campaign": f"campaign/ (manifest.json, results.parquet, results.csv, logs/); {t_campaign:.1f} s",
        "record length after the impact": f"{run.spec.duration_s:g} s",
    }, [
        ("Comparison with Table 4 of Rapp et al. 2022", _pre(format_comparison(comparison_summary) + by_preload_text(by_preload))
         + _img(TABLE4_FIGURE)
         + "<p><a href='table4_comparison.csv'>table4_comparison.csv</a></p>" + _table_html(comparison)),
        ("Characteristic map (Rapp et al. 2022, eq. 19, eq. 20)", _pre(fit.summary()) + "<p><a href='map.json'>map.json</a></p>"
         + "".join(_img(p.name) for p in map_figures)),
        ("Targets of the reference coupling", _pre(format_targets(summary["targets"]))),
        ("Map-free check: drop tests placed on the servo points", _pre(format_check(check)) if check is not None
         else "<p>no servo point inside the tested hull</p>"),
        ("Servo-hydraulic validation (Rapp et al. 2022, Fig. 14)", _pre(format_summary(validation)) + _img("fig14_servo_validation.png")
         + "<p><a href='validation.csv'>validation.csv</a>, <a href='servo_results.csv'>servo_results.csv</a></p>"
         + _table_html(validation.table)),
        ("Tests excluded from the map", _table_html(excluded_table) if len(excluded_table) else "<p>none</p>"),
    ])
    return summary


def auto_map(table: pd.DataFrame) -> dict[str, Any]:
    """``droptower map --form auto`` on ``table``: fit and cross-validated errors, the chosen
    equations, the wall time and the CPU time of this process (s, this machine)."""
    t0, c0 = time.perf_counter(), time.process_time()
    fit = fit_map(table, form="auto").to_dict()
    return {"wall_s": time.perf_counter() - t0, "cpu_s": time.process_time() - c0, **fit["fit"],
            "equations": fit["equations"]}


def portable_path(path: Path) -> str:
    """A path without this machine's folders: relative to the package's presets
    (``rig_configs/couplings/x.toml``) or the repository when inside them, else the file name."""
    path = Path(path).resolve()
    # the presets first: an installed package may sit inside the repository (.venv/lib/...)
    for root in (preset_dir("rigs").resolve().parent.parent, Path(__file__).resolve().parents[1]):
        try:
            return path.relative_to(root).as_posix()
        except ValueError:
            continue
    return path.name


def real_time_factor(coupling, rate_hz: float = RIG_SAMPLE_RATE_HZ, repeats: int = 5) -> float:
    """Simulated seconds per second of CPU time: 1 s of a 30 Hz, 1.5 deg sine at 38.4 kHz,
    single instance, best of ``repeats`` (benchmarks/bench_core.py measures it against its
    baseline). A single instance runs on one thread, so its CPU time is the wall time of an idle
    machine, which other jobs on a shared machine do not stretch."""
    x = np.radians(1.5) * np.sin(2 * np.pi * 30.0 * np.arange(1, int(rate_hz) + 1) / rate_hz)
    coupling.simulate(x[:100], 1 / rate_hz, record_energy=False)  # compiled before timing
    best = np.inf
    for _ in range(repeats):
        t0 = time.process_time()
        coupling.simulate(x, 1 / rate_hz, record_energy=False)
        best = min(best, time.process_time() - t0)
    return float(1.0 / best)


#: the reference coupling's targets: (summary path, limit, "max" or "min", what)
TARGETS = [
    (("table4", "campaign", "stiffness_rms_deviation_pct"), 5.0, "max", "campaign vs Table 4, stiffness rms %"),
    (("table4", "campaign", "damping_rms_deviation_pct"), 12.0, "max", "campaign vs Table 4, damping ratio rms %"),
    (("servo_validation", "inside", "stiffness_rms_deviation_pct"), 6.0, "max", "map vs servo inside the hull, stiffness rms %"),
    (("servo_validation", "inside", "damping_rms_deviation_pct"), 7.0, "max", "map vs servo inside the hull, damping ratio rms %"),
    (("coupling_figures", "loss_factor_ratio"), 0.7, "min", "loss factor 1 Hz / 30 Hz at 1.5 deg"),
    (("coupling_figures", "storage_rise_pct_per_decade"), 3.0, "min", "K' rise per decade, 1-30 Hz at 1.5 deg, %"),
    (("coupling_figures", "third_harmonic_pct"), 5.0, "max", "third harmonic at 1.5 deg, 30 Hz, % of fundamental"),
    (("coupling_figures", "real_time_factor"), 100.0, "min", "real-time factor, 1 s at 38.4 kHz, single instance"),
]


def target_table(summary: dict[str, Any]) -> list[dict[str, Any]]:
    """Each target of the reference coupling with the study's figure and whether it is met."""
    rows = []
    for path, limit, kind, what in TARGETS:
        value = summary
        for key in path:
            value = value[key]
        met = value <= limit if kind == "max" else value >= limit
        rows.append({"target": what, "value": float(value), "limit": limit, "kind": kind, "met": bool(met)})
    return rows


def format_targets(rows: list[dict[str, Any]]) -> str:
    return "\n".join(f"{r['target']:<58}{r['value']:>9.3g}  ({'<=' if r['kind'] == 'max' else '>='} {r['limit']:g})"
                     f"  {'met' if r['met'] else 'MISSED'}" for r in rows)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("report"), help="report folder (default: report)")
    ap.add_argument("--reduced", action="store_true", help="15 tests and fewer servo steps (CI)")
    ap.add_argument("--coupling", default=DEFAULT_COUPLING, help="coupling file or preset (default: rapp2022_nr60)")
    ap.add_argument("--workers", type=int, default=None, help="local worker processes (default: every core)")
    args = ap.parse_args(argv)
    try:
        summary = run_study(args.out, args.reduced, args.coupling, args.workers)
    except DroptowerError as exc:
        print(f"run_study: error: {exc.message}", file=sys.stderr)
        return 2
    s = summary["servo_validation"]
    print(f"{summary['coupling']}: {summary['tests']} tests, {summary['tests_extracted']} extracted, "
          f"{summary['tests_failed']} failed, {summary['tests_excluded_from_map']} excluded from the map "
          f"(campaign {summary['campaign_wall_s']:.1f} s, study {summary['study_wall_s']:.1f} s)")
    print(f"map fit: stiffness rms {summary['map_fit']['stiffness_rms_error_pct']:.2f} %, damping ratio rms "
          f"{summary['map_fit']['damping_ratio_rms_error_pct']:.2f} %")
    print(f"servo validation (stiffness rms / damping rms, %): inside the range {s['inside']['stiffness_rms_deviation_pct']:.2f}"
          f" / {s['inside']['damping_rms_deviation_pct']:.2f}, outside {s['outside']['stiffness_rms_deviation_pct']:.2f} / "
          f"{s['outside']['damping_rms_deviation_pct']:.2f}")
    print(format_comparison(summary["table4"]) + by_preload_text(summary["table4_by_preload_nm"]))
    if summary["map_free_check"] is not None:
        print(format_check(MapFreeCheck(pd.DataFrame(), summary["map_free_check"])))
    print("targets of the reference coupling:")
    print(format_targets(summary["targets"]))
    print(f"report: {args.out / 'index.html'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
