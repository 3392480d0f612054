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


def _row(summary: dict, region: str) -> dict[str, float]:
    s = summary[region]
    return {"n_points": s["n_points"], "stiffness_rms_pct": s["stiffness_rms_deviation_pct"],
            "loss_factor_rms_pct": s["loss_factor_rms_deviation_pct"], "damping_ratio_rms_pct": s["damping_rms_deviation_pct"]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="30 tests (one repeat, no preload) instead of 450")
    parser.add_argument("--families", default=",".join(ROUTES), help="the model-based routes to run")
    json_option(parser)
    args = parser.parse_args()

    from droptower.campaign import run_campaign
    from droptower.compare import run_sweeps, validate_map
    from droptower.compare.model_map import PAPER_ROUTE, model_map_from_identification, route_name
    from droptower.compare.validation import validate_routes
    from droptower.identify.dropfit import DROP_KINDS, DropFitSettings, identify_drops
    from droptower.identify.droplogs import ReadSettings, read_decays
    from droptower.maps import fit_map, read_results

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
        v = validate_map(paper, points)
        figures["routes"][PAPER_ROUTE] = {"available": True, "inside": _row(v.summary, "inside"),
                                          "outside": _row(v.summary, "outside")}
        for kind in [k.strip() for k in args.families.split(",") if k.strip()]:
            name = route_name(kind)
            if kind not in DROP_KINDS:
                print(f"{name}: not available (not a drop-test family in this version)")
                figures["routes"][name] = {"available": False}
                continue
            t0 = time.perf_counter()
            ident = identify_drops(kind, decays, excluded=excluded, options=ROUTES.get(kind, {}))
            wall = time.perf_counter() - t0
            mm = model_map_from_identification(ident, decays, DropFitSettings(), tested=paper.range, bands=False)
            vs = validate_routes({name: mm}, points, hull=paper)[name]
            verdict = ident.verdict.verdict if ident.verdict is not None else ("converged" if ident.converged else
                                                                             "not converged")
            ratio = ident.verdict.to_dict().get("error_over_noise") if ident.verdict is not None else None
            print(f"{name}: {verdict}, {wall:.0f} s", flush=True)
            figures["routes"][name] = {"available": True, "verdict": verdict, "converged": ident.converged,
                                       "error_over_noise": ratio, "wall_s": wall, "wall_over_campaign": wall / t_campaign,
                                       "inside": _row(vs.summary, "inside"), "outside": _row(vs.summary, "outside")}
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
    write_figures(args.json, "bench_routes", figures)


if __name__ == "__main__":
    sys.exit(main())
