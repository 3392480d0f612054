"""The routes from a drop-test campaign to servo-equivalent K' and loss factor (docs/routes.md).

    python benchmarks/bench_routes.py [--quick] [--json benchmarks/results/routes.json]

Data: the Table-2 campaign of ``rapp2022_nr60`` (450 tests: three cases, ten heights, three
preloads, five repeats; ``--quick``: one repeat without preload, 30 tests) on the rig ``rapp2022``.
Truth: the servo sweeps of docs/theory.md#servo run on the virtual bench with the same coupling
(validate's points). Per route, at validate's points inside the paper map's hull of the tests
(and outside it): the RMS deviation of stiffness (the paper map's c, a model's K') from the
servo's K', of the loss factor and of the drop-tower-equivalent d, and the identification's
verdict and wall time. Routes:

1. the paper's map (Rapp et al. 2022, eq. 19/20 fitted to the first-cycle readings);
2. the model-based map of every family in :data:`ROUTES` identified from the drop tests
   (``identify --from-drop-tests``; ``template`` is the preset's own structure). A family this
   version cannot fit from drop tests is listed as not available. A new family is one entry.

Baseline measured in the same run: the campaign itself (simulate, log, extract); each wall time
is printed with its ratio to it. The machine is shared: the ratio is the figure to compare.

Agreement (ISO 13528, E_n = (x_route − x_bench)/√(U_route² + U_bench²), |E_n| ≤ 1 agrees) per servo
point, stiffness and damping ratio, for the paper's map (its U95 from its tests and the rig's
inputs, :func:`droptower.uncertainty.map_uncertainty`) and the routes in ``--en-families`` (the
model map's cluster-robust bands with the inputs' shares, :mod:`droptower.uncertainty.route`),
against a bench of stated expanded uncertainty :data:`BENCH_U95_REL`; the rig's stated input
uncertainties are :data:`STATED` (assumed figures of a calibrated rig, stated here, not measured).
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

from timing import json_option, write_figures

#: the model-based routes: family -> its identify options (the table's rows, in order)
ROUTES: dict[str, dict[str, str]] = {
    "template": {"template": "rapp2022_nr60"},
    "filled_rubber": {},
    "masing": {},
    "elastoslide": {},
    "zerodim6": {},
}
COUPLING = "rapp2022_nr60"
#: the bench's own relative expanded uncertainty (95 %) the routes are judged against
BENCH_U95_REL = 0.02
#: the rig's input uncertainties the E_n numbers are computed with (standard uncertainties, normal):
#: J 1 % per fixture, lever length and laser radius 0.5 %, laser and force calibration 0.5 %,
#: flange 1 %, the clock 100 ppm (a quartz oscillator's tolerance)
STATED_FIGURES = {"inertia_rel": 0.01, "lever_length_rel": 0.005, "laser_radius_rel": 0.005,
                  "laser_calibration_rel": 0.005, "force_calibration_rel": 0.005, "torque_calibration_rel": 0.01,
                  "sample_rate_rel": 1e-4}


def stated(inertias, lever_length_m: float, laser_radius_m: float, sample_rate_hz: float):
    """:data:`STATED_FIGURES` as the rig's :class:`~droptower.uncertainty.RigUncertainty`."""
    from droptower.uncertainty import FixtureUncertainty, InputUncertainty, RigUncertainty

    f = STATED_FIGURES
    return RigUncertainty(
        inertias_kgm2=[FixtureUncertainty(nominal=j, value=f["inertia_rel"] * j) for j in sorted(set(inertias))],
        lever_length_m=InputUncertainty(value=f["lever_length_rel"] * lever_length_m),
        laser_radius_m=InputUncertainty(value=f["laser_radius_rel"] * laser_radius_m),
        laser_calibration_rel=InputUncertainty(value=f["laser_calibration_rel"]),
        force_calibration_rel=InputUncertainty(value=f["force_calibration_rel"]),
        torque_calibration_rel=InputUncertainty(value=f["torque_calibration_rel"]),
        sample_rate_hz=InputUncertainty(value=f["sample_rate_rel"] * sample_rate_hz))


def agreement_figures(agreement) -> dict:
    """Per quantity, inside the hull and in all: points judged, agreeing, the largest |E_n|; and
    every point's E_n (amplitude, frequency, in the hull)."""
    import numpy as np

    from droptower.uncertainty import AGREEMENT_QUANTITIES

    out: dict = {"bench_u95_rel": BENCH_U95_REL}
    for q in AGREEMENT_QUANTITIES:
        for region, rows in (("inside", agreement[agreement["in_range"].astype(bool)]), ("all", agreement)):
            en = np.abs(rows[f"{q}_en_number"].to_numpy(float))
            out.setdefault(region, {})[q] = {"n_points": int(en.size), "agree": int((en <= 1).sum()),
                                             "max_abs_en": float(np.nanmax(en)) if en.size else None}
    out["points"] = [{"amplitude_deg": float(r["amplitude_deg"]), "frequency_hz": float(r["frequency_hz"]),
                      "in_range": bool(r["in_range"]),
                      **{f"{q}_en_number": float(r[f"{q}_en_number"]) for q in AGREEMENT_QUANTITIES}}
                     for _, r in agreement.iterrows()]
    return out


def _row(summary: dict, region: str) -> dict[str, float]:
    s = summary[region]
    return {"n_points": s["n_points"], "stiffness_rms_pct": s["stiffness_rms_deviation_pct"],
            "loss_factor_rms_pct": s["loss_factor_rms_deviation_pct"], "damping_ratio_rms_pct": s["damping_rms_deviation_pct"]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="30 tests (one repeat, no preload) instead of 450")
    parser.add_argument("--families", default=",".join(ROUTES), help="the model-based routes to run")
    parser.add_argument("--en-families", default="template",
                        help="the model-based routes judged by E_n (their bands and inputs' shares cost a Jacobian)")
    json_option(parser)
    args = parser.parse_args()

    from droptower.campaign import run_campaign
    from droptower.compare import compare_with_servo, run_sweeps
    from droptower.compare.model_map import PAPER_ROUTE, model_map_from_identification, route_name
    from droptower.compare.map_vs_servo import validate_routes
    from droptower.identify.dropfit import DROP_KINDS, DropFitSettings, identify_drops
    from droptower.identify.droplogs import ReadSettings, read_decays
    from droptower.maps import fit_map, read_results
    from droptower.uncertainty import map_uncertainty, route_agreement
    from droptower.uncertainty.route import nominal_geometry

    figures: dict[str, object] = {"coupling": COUPLING, "plan": "quick" if args.quick else "table2", "routes": {}}
    with tempfile.TemporaryDirectory() as tmp:
        plan = None
        if args.quick:  # Table 2's cases and heights, one repeat, no preload
            import tomli_w

            from droptower.configs import read_toml, resolve

            doe = read_toml(resolve("rapp2022_table2", "doe")) | {"repeats": 1, "preloads_nm": [0.0]}
            plan = Path(tmp) / "plan.toml"
            plan.write_text(tomli_w.dumps(doe))
        t0 = time.perf_counter()
        run_campaign(f"{tmp}/campaign", None, COUPLING, plan, workers=2, progress=False)
        t_campaign = time.perf_counter() - t0
        results = read_results(f"{tmp}/campaign")
        paper = fit_map(results, source="campaign")
        t0 = time.perf_counter()
        points = run_sweeps(COUPLING)
        t_bench = time.perf_counter() - t0
        decays, excluded = read_decays([f"{tmp}/campaign"], ReadSettings())
        figures.update(tests=len(results), campaign_s=t_campaign, bench_sweeps_s=t_bench)
        print(f"campaign: {len(results)} tests of {COUPLING} in {t_campaign:.1f} s (the baseline); servo sweeps on the "
              f"bench {t_bench:.1f} s; {len(decays)} decays read ({len(excluded)} excluded)")
        v = compare_with_servo(paper, points)
        lever, laser = nominal_geometry(decays)
        inputs = stated(results["inertia_kgm2"], lever, laser, 1.0 / decays[0].dt_s)
        figures["stated_inputs"] = dict(STATED_FIGURES)
        if "sensor_radius_m" not in results.columns:  # a campaign's table: its rig's laser, as its logs say
            results = results.assign(sensor_radius_m=laser)
        bands = map_uncertainty(results, inputs, map_fit=paper).predict(v.table["amplitude_deg"], v.table["frequency_hz"])
        en = route_agreement(v.table, {q: bands[f"{q}_U95"].to_numpy() for q in ("stiffness_nm_per_deg", "damping_ratio")},
                             u95_ref_rel=BENCH_U95_REL)
        figures["routes"][PAPER_ROUTE] = {"available": True, "inside": _row(v.summary, "inside"),
                                          "outside": _row(v.summary, "outside"), "agreement": agreement_figures(en)}
        judged = {k.strip() for k in args.en_families.split(",") if k.strip()}
        for kind in [k.strip() for k in args.families.split(",") if k.strip()]:
            name = route_name(kind)
            if kind not in DROP_KINDS:
                print(f"{name}: not available (not a drop-test family in this version)")
                figures["routes"][name] = {"available": False}
                continue
            t0 = time.perf_counter()
            ident = identify_drops(kind, decays, excluded=excluded, options=ROUTES.get(kind, {}))
            wall = time.perf_counter() - t0
            t0 = time.perf_counter()
            mm = model_map_from_identification(ident, decays, DropFitSettings(), tested=paper.range,
                                               bands=kind in judged, uncertainty=inputs if kind in judged else None,
                                               lever_length_m=lever, laser_radius_m=laser)
            vs = validate_routes({name: mm}, points, hull=paper)[name]
            en_wall = time.perf_counter() - t0
            verdict = ident.verdict.verdict if ident.verdict is not None else ("converged" if ident.converged else
                                                                             "not converged")
            ratio = ident.verdict.to_dict().get("error_over_noise") if ident.verdict is not None else None
            print(f"{name}: {verdict}, {wall:.0f} s", flush=True)
            figures["routes"][name] = {"available": True, "verdict": verdict, "converged": ident.converged,
                                       "error_over_noise": ratio, "wall_s": wall, "wall_over_campaign": wall / t_campaign,
                                       "inside": _row(vs.summary, "inside"), "outside": _row(vs.summary, "outside")}
            if kind in judged:
                from droptower.compare.validate import model_route_u95

                en = route_agreement(vs.table, model_route_u95(mm, vs.table), u95_ref_rel=BENCH_U95_REL)
                figures["routes"][name]["agreement"] = agreement_figures(en)
                figures["routes"][name]["bands_and_inputs_s"] = en_wall
        print(f"\n{'route':<34}{'points':>7}{'K rms %':>9}{'eta rms %':>10}{'d rms %':>9}   verdict, wall (ratio to the "
              "campaign)   [inside the hull; outside: K / eta rms %]")
        for name, r in figures["routes"].items():
            if not r["available"]:
                print(f"{name:<34}  not available")
                continue
            i, o = r["inside"], r["outside"]
            tail = "-" if "wall_s" not in r else f"{r['verdict']}, {r['wall_s']:.0f} s ({r['wall_over_campaign']:.1f}x)"
            print(f"{name:<34}{i['n_points']:>7}{i['stiffness_rms_pct']:>9.1f}{i['loss_factor_rms_pct']:>10.1f}"
                  f"{i['damping_ratio_rms_pct']:>9.1f}   {tail}   [outside: {o['stiffness_rms_pct']:.1f} / "
                  f"{o['loss_factor_rms_pct']:.1f}]")
    print(f"\nE_n against the bench (U95 {100 * BENCH_U95_REL:g} %), inside the hull: agreeing points, max |E_n|")
    for name, r in figures["routes"].items():
        a = r.get("agreement")
        if a is not None:
            print(f"{name:<34}" + "; ".join(f"{q} {s['agree']}/{s['n_points']} (max {s['max_abs_en']:.2f})"
                                            for q, s in a["inside"].items()))
    write_figures(args.json, "bench_routes", figures)


if __name__ == "__main__":
    sys.exit(main())
