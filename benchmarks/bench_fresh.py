"""Benchmark: the commands as a user meets them, each a fresh process, against the previous release
measured in the same run.

The in-process benchmarks (``bench_extract.py``, ``bench_campaign.py``) time the work; a user
pays the interpreter, the imports, the kernel loading and the files written too. Each figure is
the best-of-N wall time of a fresh ``python`` process (``subprocess``) and the CPU time
(user + system) of that process and its workers (``RUSAGE_CHILDREN``), which other jobs on the
machine hardly stretch, for this checkout and for the baseline, a copy of the previous release
(``git archive`` of ``--baseline``, default :data:`RELEASE`) run the same way in the same run,
interleaved. Each command runs once untimed first (the numba cache of each copy is filled then; the
routes' first run reads a few logs only).

1. ``python -m droptower extract ONE_FILE --out r.csv``, one 10 000-sample log
   (target <= 1.0 s wall);
2. ``python -c "from droptower.extract import extract_file"`` (target <= 0.5 s wall);
3. ``python -m droptower campaign --out DIR --workers 2``, the README's command: Table 2,
   450 tests (target <= 5 s wall on an unloaded 2-core machine); with ``--large`` also the
   Table-2 plan with 50 repeats (4 500 tests), this checkout only, once (target <= 10x the
   450-test run);
4. the core in a fresh process: 1 s at 38.4 kHz of the reference coupling ``rapp2022_nr60``
   driven by a 10 Hz sine of 1 deg, best of 15 calls after a first one (target >= 200x real
   time);
5. ``python -m droptower map DIR --plot DIR/map``, the README's first command's second step, on
   each copy's own 450-test campaign (the last of item 3's runs);
6. the model route, ``python -m droptower identify --from-drop-tests DIR --model filled_rubber
   --out fitted.toml`` on this checkout's 450-test campaign (target <= 30 s wall), once after an
   untimed run on :data:`ROUTE_WARM_UP_TESTS` of its logs (which loads the fit's kernels into the
   numba cache); its accuracy as ``bench_routes.py`` defines it: the fitted coupling's servo K'
   and loss factor against the virtual bench's on the same coupling, RMS deviation at
   validate's points inside the paper map's hull. The previous release fits no filled_rubber
   to drop tests, so the ratio is that of the ``template`` route (``--model template
   --template rapp2022_nr60``), which both copies run on their own campaigns, likewise once
   after an untimed run on a few logs.

    python benchmarks/bench_fresh.py [--repeat 5] [--campaign-repeat 3] [--map-repeat 3] [--baseline REF] [--large]
    python benchmarks/bench_fresh.py --large --json benchmarks/results/fresh.json
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from timing import json_option, write_figures

ROOT = Path(__file__).resolve().parents[1]
#: the previous release, 0.1.0 (CHANGELOG.md, 2026-11-25): the last commit on main that day
RELEASE = "91d64c0"
RELEASE_LABEL = "0.1.0"
TARGETS = {"extract_wall_s": 1.0, "import_wall_s": 0.5, "campaign_wall_s": 5.0, "campaign_large_over_450": 10.0,
           "core_real_time_factor": 200.0, "route_wall_s": 30.0}
#: the model route's family (the README's route table) and the coupling the campaign simulates
ROUTE_MODEL = "filled_rubber"
COUPLING = "rapp2022_nr60"
#: logs of the untimed first run of the model route (it fills the numba cache of the fit's kernels)
ROUTE_WARM_UP_TESTS = 12
LARGE_REPEATS = 50  # Table 2's 90 conditions x 50 = 4 500 tests
CORE = """
import json, time
import numpy as np
from droptower.rheology import load_coupling
model = load_coupling("rapp2022_nr60")
h = 1.0 / 38400.0
x = np.deg2rad(1.0) * np.sin(2.0 * np.pi * 10.0 * np.arange(1, 38401) * h)
model.respond(x, h)
walls, cpus = [], []
for _ in range(15):
    t, c = time.perf_counter(), time.process_time()
    model.respond(x, h)
    walls.append(time.perf_counter() - t)
    cpus.append(time.process_time() - c)
print(json.dumps({"wall_s": min(walls), "cpu_s": min(cpus)}))
"""


def children_cpu_s() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def fresh(code_root: Path, args: list[str], cwd: Path) -> tuple[float, float, str]:
    """Run ``python ARGS`` with ``code_root`` on the path, from ``cwd``; (wall s, CPU s of it and its
    children, stdout). A failed command stops the benchmark with its stderr."""
    env = {**os.environ, "PYTHONPATH": str(code_root)}
    cpu, t0 = children_cpu_s(), time.perf_counter()
    done = subprocess.run([sys.executable, *args], cwd=cwd, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if done.returncode != 0:
        raise SystemExit(f"bench_fresh: `python {' '.join(args)}` on {code_root} failed:\n{done.stderr[-2000:]}")
    return wall, children_cpu_s() - cpu, done.stdout


def export(ref: str, folder: Path) -> Path:
    """The package and its presets at commit ``ref`` (``git archive``), unpacked into ``folder``."""
    folder.mkdir(parents=True)
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", ref, "droptower", "rig_configs"], capture_output=True, check=True)
    subprocess.run(["tar", "-x", "-C", str(folder)], input=archive.stdout, check=True)
    # also as the package ``droptower.rig_configs`` (its installed place): an editable install of
    # another checkout maps that name to its own presets, which a copy of an older release may not read
    shutil.copytree(folder / "rig_configs", folder / "droptower" / "rig_configs")
    return folder


def best(code_roots: dict[str, Path], make_args, cwd: Path, repeat: int) -> dict[str, tuple[float, float]]:
    """Per copy, (best wall s, best CPU s) of ``repeat`` runs after one untimed, the copies interleaved."""
    runs: dict[str, list[tuple[float, float]]] = {name: [] for name in code_roots}
    for i in range(repeat + 1):
        for name, root in code_roots.items():
            wall, cpu, _ = fresh(root, make_args(name, i), cwd)
            if i:
                runs[name].append((wall, cpu))
    return {name: (min(w for w, _ in r), min(c for _, c in r)) for name, r in runs.items()}


def large_plan(folder: Path) -> Path:
    """Table 2 with :data:`LARGE_REPEATS` repeats per condition (the shipped plan has 5)."""
    text = (ROOT / "rig_configs" / "doe" / "rapp2022_table2.toml").read_text()
    assert "repeats = 5" in text
    path = folder / "table2_large.toml"
    path.write_text(text.replace("repeats = 5", f"repeats = {LARGE_REPEATS}", 1).replace(
        'name = "rapp2022_table2"', f'name = "rapp2022_table2_x{LARGE_REPEATS}"', 1))
    return path


def route_accuracy(campaign: Path, coupling_file: Path) -> dict[str, float]:
    """The fitted coupling's servo K' and loss factor against the virtual bench's on
    :data:`COUPLING`, as ``bench_routes.py`` judges a model route: RMS deviation (%) at
    validate's points inside (and outside) the hull of the paper map fitted to ``campaign``."""
    from droptower.compare import run_sweeps
    from droptower.compare.map_vs_servo import validate_routes
    from droptower.compare.model_map import model_map_from_coupling, route_name
    from droptower.maps import fit_map, read_results
    from droptower.rheology import load_coupling

    paper = fit_map(read_results(campaign), source="campaign")
    name = route_name(ROUTE_MODEL)
    mm = model_map_from_coupling(load_coupling(str(coupling_file)), paper.range, family=ROUTE_MODEL)
    summary = validate_routes({name: mm}, run_sweeps(COUPLING), hull=paper)[name].summary
    return {f"route_{region}_{key}": summary[region][f"{what}_rms_deviation_pct"]
            for region in ("inside", "outside") for key, what in (("stiffness_rms_pct", "stiffness"),
                                                                  ("loss_factor_rms_pct", "loss_factor"))} | {
        "route_inside_points": summary["inside"]["n_points"]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5, help="runs of each short command per copy (best of)")
    parser.add_argument("--campaign-repeat", type=int, default=3, help="runs of the 450-test campaign per copy")
    parser.add_argument("--map-repeat", type=int, default=3, help="runs of the map of the 450 tests per copy")
    parser.add_argument("--baseline", default=RELEASE, help=f"git ref of the baseline (default {RELEASE}, "
                        f"release {RELEASE_LABEL})")
    parser.add_argument("--large", action="store_true", help="also the 4 500-test campaign (this checkout, once)")
    json_option(parser)
    args = parser.parse_args()

    tmp = Path(tempfile.mkdtemp(prefix="bench_fresh_"))
    try:
        roots = {"new": ROOT, "baseline": export(args.baseline, tmp / "baseline")}
        sys.path.insert(0, str(ROOT))
        from droptower.extract.synthetic import SyntheticDrop
        from droptower.rates import RIG_SAMPLE_RATE_HZ

        log = SyntheticDrop(stiffness_nm_per_rad=1.5e4, damping_ratio=1.2, amplitude_deg=1.0, ringing_fraction=0.3,
                            duration_s=10_000 / RIG_SAMPLE_RATE_HZ, sample_rate_hz=RIG_SAMPLE_RATE_HZ,
                            seed=1).write(tmp / "one.csv")
        figures: dict[str, object] = {"baseline_ref": args.baseline, "baseline_label": RELEASE_LABEL
                                      if args.baseline == RELEASE else args.baseline,
                                      "repeat": args.repeat, "campaign_repeat": args.campaign_repeat,
                                      "targets": TARGETS}

        def record(key: str, result: dict[str, tuple[float, float]]) -> None:
            (wall, cpu), (base_wall, base_cpu) = result["new"], result["baseline"]
            figures.update({f"{key}_wall_s": wall, f"{key}_cpu_s": cpu, f"{key}_baseline_wall_s": base_wall,
                            f"{key}_baseline_cpu_s": base_cpu, f"{key}_speed_up_wall": base_wall / wall,
                            f"{key}_speed_up_cpu": base_cpu / cpu})
            print(f"{key:>9}: {wall:6.2f} s wall, {cpu:6.2f} s CPU; {figures['baseline_label']}: {base_wall:6.2f} s "
                  f"wall, {base_cpu:6.2f} s CPU -> {base_wall / wall:4.1f}x wall, {base_cpu / cpu:4.1f}x CPU", flush=True)

        record("import", best(roots, lambda name, i: ["-c", "from droptower.extract import extract_file"], tmp,
                              args.repeat))
        record("extract", best(roots, lambda name, i: ["-m", "droptower", "extract", str(log), "--out",
                                                       str(tmp / f"r_{name}.csv"), "--quiet"], tmp, args.repeat))

        def campaign(name: str, i: int) -> list[str]:
            out = tmp / f"campaign_{name}_{i}"
            shutil.rmtree(out, ignore_errors=True)
            return ["-m", "droptower", "campaign", "--out", str(out), "--workers", "2", "--quiet"]
        record("campaign", best(roots, campaign, tmp, args.campaign_repeat))
        campaigns = {name: tmp / f"campaign_{name}_{args.campaign_repeat}" for name in roots}  # each copy's last

        record("map", best(roots, lambda name, i: ["-m", "droptower", "map", str(campaigns[name]), "--plot",
                                                   str(campaigns[name] / "map"), "--quiet"], tmp, args.map_repeat))

        def route(name: str, model: list[str], out: Path, data: list[Path] | None = None) -> list[str]:
            return ["-m", "droptower", "identify", "--from-drop-tests", *map(str, data or [campaigns[name]]), *model,
                    "--out", str(out), "--accept-poor", "--quiet"]

        def warm_up(name: str, model: list[str]) -> list[str]:
            """The route on a few of the campaign's logs: the fit's kernels loaded into the numba cache."""
            logs = sorted((campaigns[name] / "logs").iterdir())
            return route(name, model, tmp / f"warm_up_{name}.toml", logs[::len(logs) // ROUTE_WARM_UP_TESTS])

        template = ["--model", "template", "--template", COUPLING]
        for name, root in roots.items():
            fresh(root, warm_up(name, template), tmp)
        record("route_template", {name: fresh(root, route(name, template, tmp / f"template_{name}.toml"), tmp)[:2]
                                  for name, root in roots.items()})
        model = ["--model", ROUTE_MODEL]
        logs = sorted((campaigns["new"] / "logs").iterdir())
        fresh(ROOT, warm_up("new", model), tmp)
        wall, cpu, report = fresh(ROOT, route("new", model, tmp / "fitted.toml"), tmp)
        verdict = next((line.split(":", 1)[1].split("(")[0].strip() for line in report.splitlines()
                        if line.startswith("verdict:")), "none printed")
        figures.update({"route_model": ROUTE_MODEL, "route_tests": len(logs), "route_wall_s": wall, "route_cpu_s": cpu,
                        "route_verdict": verdict,
                        **route_accuracy(campaigns["new"], tmp / "fitted.toml"),
                        "route_baseline": f"{figures['baseline_label']} fits no {ROUTE_MODEL} to drop tests: the "
                                          "ratio is the template route's"})
        print(f"    route: {ROUTE_MODEL} on {len(logs)} tests {wall:6.2f} s wall, {cpu:6.2f} s CPU; K' "
              f"{figures['route_inside_stiffness_rms_pct']:.3f} %, loss factor "
              f"{figures['route_inside_loss_factor_rms_pct']:.3f} % RMS against the bench "
              f"({figures['route_inside_points']} points inside the hull)", flush=True)

        core = {}
        for name, root in roots.items():
            runs = [json.loads(fresh(root, ["-c", CORE], tmp)[2]) for _ in range(3)]
            core[name] = (min(r["wall_s"] for r in runs), min(r["cpu_s"] for r in runs))
        figures.update({"core_wall_ms": 1e3 * core["new"][0], "core_cpu_ms": 1e3 * core["new"][1],
                        "core_real_time_factor": 1.0 / core["new"][0], "core_real_time_factor_cpu": 1.0 / core["new"][1],
                        "core_baseline_real_time_factor": 1.0 / core["baseline"][0],
                        "core_baseline_real_time_factor_cpu": 1.0 / core["baseline"][1]})
        print(f"     core: {1.0 / core['new'][0]:.0f}x real time ({1.0 / core['new'][1]:.0f}x on CPU time); "
              f"{figures['baseline_label']}: {1.0 / core['baseline'][0]:.0f}x ({1.0 / core['baseline'][1]:.0f}x)")

        if args.large:
            out = tmp / "campaign_large"
            wall, cpu, _ = fresh(ROOT, ["-m", "droptower", "campaign", "--out", str(out), "--doe",
                                        str(large_plan(tmp)), "--workers", "2", "--quiet"], tmp)
            figures.update({"campaign_large_tests": 90 * LARGE_REPEATS, "campaign_large_wall_s": wall,
                            "campaign_large_cpu_s": cpu, "campaign_large_over_450": wall / figures["campaign_wall_s"],
                            "campaign_large_over_450_cpu": cpu / figures["campaign_cpu_s"]})
            print(f"campaign of {90 * LARGE_REPEATS} tests: {wall:.1f} s wall ({wall / figures['campaign_wall_s']:.1f}x "
                  f"the 450-test run), {cpu:.1f} s CPU ({cpu / figures['campaign_cpu_s']:.1f}x)")
        for key, target in TARGETS.items():
            if key in figures:
                met = figures[key] >= target if key.endswith("factor") else figures[key] <= target
                print(f"  {key}: {figures[key]:.3g} (target {'>=' if key.endswith('factor') else '<='} {target:g}): "
                      f"{'met' if met else 'missed'}")
        write_figures(args.json, "bench_fresh", figures)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
