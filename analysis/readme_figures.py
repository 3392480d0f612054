"""The documentation's measured figures from one place: the stored full study
(``analysis/results/``: ``summary.json``, the calibration's tables, the map command's nested
cross-validation of Table 4), the benchmarks' figures (``benchmarks/results/*.json`` and the
printouts ``identify_random.txt``, ``identify_filled_rubber.txt``) and the figures tests store
(``tests/data/regression/*.json``, ``python tests/regenerate.py``), rendered into the blocks that
README.md, the documentation pages (:data:`BLOCKS`) and ``analysis/README.md`` mark with
``<!-- figures:NAME -->`` ... ``<!-- /figures -->``. A measured figure outside a block fails
``tests/test_doc_figures.py`` unless it is listed there with why it is not today's measurement.

    python analysis/readme_figures.py                # re-run the full study and every benchmark,
                                                     # store their results, rewrite the blocks
    python analysis/readme_figures.py --render-only  # rewrite the blocks from the stored results
    python analysis/readme_figures.py --skip-benchmarks | --skip-study

``tests/test_readme_figures.py`` renders every block from the stored results and fails when a
page disagrees with it: figures of the study and accuracies exactly as printed; times, rates
and effort counts within :data:`MACHINE_NOISE` or :data:`CPU_NOISE` (stated in the page next to
them), so a re-run benchmark on the same machine class needs no page change.
"""
from __future__ import annotations

import argparse
import difflib
import json
import math
import re
import shutil
import string
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

ROOT = Path(__file__).resolve().parents[1]
STUDY_RESULTS = ROOT / "analysis" / "results"
#: the study's files that are stored (the rest of its report folder is regenerated at will)
STUDY_FILES = ("summary.json", "table4_comparison.csv")
#: ``auto``'s choice of terms cross-validated on Table 4 (nested), as the map command writes it
NESTED_MAP = STUDY_RESULTS / "table4_map_nested.json"
NESTED_MAP_COMMAND = ("-m", "droptower", "map", "rapp2022_table4", "--form", "auto", "--nested-cv", "--json")
BENCH_RESULTS = ROOT / "benchmarks" / "results"
#: stored benchmark figures: name -> the script that writes them with ``--json``
BENCHMARKS = {"core": "bench_core.py", "rig": "bench_rig.py", "extract": "bench_extract.py",
              "campaign": "bench_campaign.py", "identify": "bench_identify.py", "routes": "bench_routes.py"}
#: stored figures of a benchmark run with arguments (name -> the command line after ``python benchmarks/``):
#: rendered into their own blocks, not into the benchmark table's machine line
BENCHMARK_RUNS = {"identify_hard": ("bench_identify.py", "--random", "--hard"),
                  "report": ("bench_report.py", "--n", "4500"),
                  "campaign_dask": ("bench_campaign.py", "--dask", "--n", "45000"),
                  "uncertainty_coverage": ("bench_uncertainty_coverage.py", "--campaigns", "2000"),
                  "uncertainty_route": ("bench_uncertainty_route.py", "--campaigns", "1000", "--workers", "2"),
                  "fresh": ("bench_fresh.py", "--large"), "compile": ("bench_compile.py",),
                  "uncertainty": ("bench_uncertainty.py",)}
#: figures that tests store (tests/data/regression/<test module>.json, ``python tests/regenerate.py``)
TEST_FIGURES = ROOT / "tests" / "data" / "regression"
#: wall times of a re-run on the same shared 2-core machine lie within this factor: they move with the
#: other jobs' load (bench_core's 1 s of the composition, best of 7: 12.8, 16.8, 30.1, 28.8 ms within 15
#: minutes and 23.3 ms later, at load averages 6-12; 9.3-9.9 ms when the machine was quiet)
MACHINE_NOISE = 2.5
#: CPU times (of one thread), their ratios and effort counts of a re-run lie within this factor: other
#: jobs hardly stretch them (the same runs: 9.05 and 8.90 ms CPU time, solve_ivp ratio 141 and 142;
#: the extraction's CPU-time rate 165 and 162 logs/s at load averages 10 and 12)
CPU_NOISE = 1.25
START, END = "<!-- figures:{} -->", "<!-- /figures -->"
SPEED_TARGET = "real-time factor, 1 s at 38.4 kHz, single instance"  # a target of run_study.TARGETS


@dataclass(frozen=True)
class Figure:
    """One number of a block: as printed, and the factor a re-run may differ by (1: must read the same)."""

    text: str
    noise: float = 1.0


def exact(value: float, fmt: str) -> Figure:
    """A figure that must read exactly as the stored value prints (computed, not timed)."""
    return Figure(format(value, fmt))


def timed(value: float, fmt: str) -> Figure:
    """A wall time (or a rate, or a figure that depends on one): equal within :data:`MACHINE_NOISE`."""
    return Figure(format(value, fmt), MACHINE_NOISE)


def on_cpu(value: float, fmt: str) -> Figure:
    """A CPU time, a ratio of CPU times or an effort count: equal within :data:`CPU_NOISE`."""
    return Figure(format(value, fmt), CPU_NOISE)


Block = list  # of str (text) and Figure (numbers), in order


def fill(template: str, **figures: Figure) -> Block:
    """``template`` with its ``{name}`` fields replaced by ``figures`` (kept apart for the check)."""
    pieces: Block = []
    for literal, field, _, _ in string.Formatter().parse(template):
        pieces.append(literal)
        if field is not None:
            pieces.append(figures[field])
    return pieces


def text(block: Block) -> str:
    return "".join(p.text if isinstance(p, Figure) else p for p in block)


NUMBER = r"(-?\d[\d,]*(?:\.\d+)?(?:e[-+]?\d+)?)"


def disagreements(written: str, block: Block) -> list[str]:
    """Where ``written`` (a page's block) disagrees with ``block`` rendered from the stored results:
    [] when the words are the same, every computed figure reads the same and every measured one lies
    within its noise (:data:`MACHINE_NOISE`, :data:`CPU_NOISE`)."""
    pattern = "".join(NUMBER if isinstance(p, Figure) else re.escape(p) for p in block)
    match = re.fullmatch(r"\n*" + pattern + r"\n*", written)  # the blank lines around a block do not count
    if match is None:
        diff = difflib.unified_diff(written.strip("\n").splitlines(), text(block).strip("\n").splitlines(),
                                    "written", "rendered from the stored results", lineterm="", n=0)
        return ["the words differ:\n" + "\n".join(diff)]
    problems = []
    figures = [p for p in block if isinstance(p, Figure)]
    for found, figure in zip(match.groups(), figures):
        if found == figure.text:
            continue
        if figure.noise == 1.0:
            problems.append(f"{found} where the stored results give {figure.text}")
            continue
        have, want = float(found.replace(",", "")), float(figure.text.replace(",", ""))
        if want <= 0 or have <= 0 or abs(math.log(have / want)) > math.log(figure.noise) + 1e-12:
            problems.append(f"{found} where the stored benchmark gives {figure.text} (beyond the machine noise, "
                            f"a factor {figure.noise:g})")
    return problems


# --- the blocks -----------------------------------------------------------------------------

def load_stored() -> dict[str, Any]:
    """The stored study summary (``study``) and each stored benchmark's figures (by name)."""
    stored = {"study": json.loads((STUDY_RESULTS / "summary.json").read_text()),
              "map_nested": json.loads(NESTED_MAP.read_text())}
    for name in (*BENCHMARKS, *BENCHMARK_RUNS):
        stored[name] = json.loads((BENCH_RESULTS / f"{name}.json").read_text())
    stored["tests"] = {path.stem: json.loads(path.read_text()) for path in sorted(TEST_FIGURES.glob("*.json"))}
    return stored


def pct(value: float) -> str:
    """A deviation in % with three significant figures at most (5.30, 11.4, 0.12)."""
    return ".2f" if abs(value) < 10 else ".1f"


def machine_line(records: dict[str, dict[str, Any]]) -> Block:
    """The line above a table of benchmarks: when and on what each was measured (by name), the load."""
    runs: dict[tuple[str, str], list[str]] = {}
    for name, r in records.items():
        runs.setdefault((r["machine"]["date"], r["machine"]["processor"]), []).append(f"`bench_{name}`")
    when = "; ".join(f"{', '.join(names)} {date} ({processor})" for (date, processor), names in sorted(runs.items()))
    m = next(iter(records.values()))["machine"]
    loads = [r["machine"][k] for r in records.values() for k in ("load_average_start", "load_average_end")]
    return fill(f"Measured on {m['cores']} cores, Python {m['python']}: {when}; load "
                "average {lo}–{hi}. Times are best-of-N wall times, which other jobs on the machine stretch (the "
                f"load average says how much): a re-run on this machine class lands within a factor {MACHINE_NOISE:g} "
                f"of them, CPU times, their ratios and evaluation counts within a factor {CPU_NOISE:g} (the machine "
                "noise `tests/test_readme_figures.py` allows). The scripts print the baseline measured in the same "
                "run.\n",
                lo=timed(min(loads), ".1f"), hi=timed(max(loads), ".1f"))


def bench_table(stored: dict[str, Any]) -> Block:
    core, rig, ext, camp, ident = (stored[k]["figures"] for k in ("core", "rig", "extract", "campaign", "identify"))
    drops = ident["drops"].values()
    walls = [d["wall_s"] for d in drops]
    ratios = [d["wall_s"] / d["rig_s"] for d in drops]
    elements = " + ".join(core["coupling_elements"])
    return machine_line({k: stored[k] for k in ("core", "rig", "extract", "campaign", "identify")}) + fill(
        "\n| benchmark | figure | target |\n|---|---|---|\n"
        "| core, a 32-element rate-dependent elastoslide composition (spring + elastoslide with p = 7 + two Maxwell "
        "branches), 1 s at 38.4 kHz | {c_ms} ms ({c_rt}× real time; CPU time {c_cpu} ms) | ≤ 10 ms |\n"
        f"| core, the reference coupling `{core['coupling']}` ({elements}), 1 s at 38.4 kHz "
        "| {n_ms} ms ({n_rt}× real time; CPU time {n_cpu} ms) | ≥ 100× |\n"
        f"| core, batch of 450 × 0.25 s of `{core['coupling']}` at 38.4 kHz | {{batch}} s | ≤ 2 s |\n"
        "| core vs `scipy.integrate.solve_ivp` (Radau, analytic Jacobian) on the elastoslide composition, equal "
        "peak-torque accuracy (≤ 0.5 %), CPU time, best of N each | {ivp}× faster | ≥ 100× |\n"
        "| rig, one 0.25 s drop test at 38.4 kHz, reference coupling | {rig1} s | ≤ 0.3 s |\n"
        f"| rig, {rig['tests']} tests of 0.25 s each batched (longer records than a campaign's), {rig['workers']} workers "
        "| {rigb} s | ≤ 30 s |\n"
        "| extraction, 10 000-sample CSV logs, parsing included | {ext} logs/s ({ext_cpu} on CPU time; parsing {share} %) "
        "| ≥ 100 logs/s |\n"
        "| campaign, Table 2 (450 tests simulated, logged, extracted) | {camp} s, peak memory ≤ {mem} GB "
        "| ≤ 60 s, ≤ 2 GB |\n"
        f"| identification, {ident['servo']['seconds_of_data']:.0f} s of 2048 Hz data | six-parameter {{z6}} s "
        "({z6e} evaluations), elastoslide {es} s ({ese}) | ≤ 10 s, ≤ 60 s |\n"
        "| identification from 12 drop tests (elastoslide, zerodim6-type, masing-type) | {dlo}–{dhi} s each "
        "({rlo}–{rhi}× the rig simulating the same tests) | ≤ 60 s |\n"
        "| identification from the Table-2 campaign (450 tests), `template rapp2022_nr60` | {t2} s "
        "({t2r}× the campaign itself, {t2c} s in the same run) | ≤ 5 min |\n",
        c_ms=timed(core["composition_single_1s_ms"], ".1f"), c_rt=timed(core["composition_real_time_factor"], ".0f"),
        n_ms=timed(core["coupling_single_1s_ms"], ".1f"), n_rt=timed(core["coupling_real_time_factor"], ".0f"),
        c_cpu=on_cpu(core["composition_single_1s_cpu_ms"], ".1f"), n_cpu=on_cpu(core["coupling_single_1s_cpu_ms"], ".1f"),
        batch=timed(core["batch_450_s"], ".2f"), ivp=on_cpu(core["solve_ivp_over_core"], ".0f"),
        rig1=timed(rig["single_test_s"], ".2f"), rigb=timed(rig["batched_s"], ".1f"),
        ext=timed(ext["wall_logs_per_s"], ".0f"), ext_cpu=on_cpu(ext["cpu_logs_per_s"], ".0f"),
        share=timed(ext["wall_parsing_share_pct"], ".0f"),
        camp=timed(camp["wall_s"], ".1f"), mem=timed(camp["peak_memory_bound_mb"] / 1024, ".2f"),
        z6=timed(ident["servo"]["zerodim6_wall_s"], ".1f"), z6e=on_cpu(ident["servo"]["zerodim6_evaluations"], "d"),
        es=timed(ident["servo"]["elastoslide_wall_s"], ".1f"), ese=on_cpu(ident["servo"]["elastoslide_evaluations"], "d"),
        dlo=timed(min(walls), ".0f"), dhi=timed(max(walls), ".0f"), rlo=timed(min(ratios), ".1f"),
        rhi=timed(max(ratios), ".1f"), t2=timed(ident["table2"]["wall_s"], ".0f"),
        t2r=timed(ident["table2"]["wall_s"] / ident["table2"]["campaign_s"], ".1f"),
        t2c=timed(ident["table2"]["campaign_s"], ".1f"))


def identify_drops(stored: dict[str, Any]) -> Block:
    ident = stored["identify"]["figures"]
    d, t2 = ident["drops"], ident["table2"]
    return fill(
        "Measured (virtual campaigns of couplings the fit does not know, rig sensor noise, 12 tests over the three "
        "inertias and heights 0.1–3 m; servo grid 4 amplitudes × 3 frequencies inside the tested range; "
        "`benchmarks/bench_identify.py`): elastoslide K' {e_k} % / loss factor {e_l} % RMS, zerodim6-type {z_k} % / "
        "{z_l} %, masing-type {m_k} % / {m_l} % (acceptance ≤ 3 % / ≤ 10 %). On the Table-2 campaign of "
        f"`rapp2022_nr60` ({t2['tests']} tests used) its own composition (`template`, the elements' settings such as "
        "the power-law band kept) converges in {wall} s of wall time at the load stated under Benchmarks ({evals} "
        "evaluations) with an angle nRMSE of {fit} % "
        "(hold-out {hold} %).\n",
        **{f"{k[0]}_k": exact(d[k]["storage_stiffness_rms_pct"], ".2f") for k in ("elastoslide", "zerodim6", "masing")},
        **{f"{k[0]}_l": exact(d[k]["loss_factor_rms_pct"], ".2f") for k in ("elastoslide", "zerodim6", "masing")},
        wall=timed(t2["wall_s"], ".0f"), evals=on_cpu(t2["evaluations"], "d"),
        fit=exact(t2["angle_nrmse_fit_pct"], ".2f"), hold=exact(t2["angle_nrmse_holdout_pct"], ".2f"))


def identify_hard(stored: dict[str, Any]) -> Block:
    run = stored["identify_hard"]
    fams = run["figures"]["families"]
    rows, figures = [], {}
    for kind, f in fams.items():
        rows.append(f"| {kind} | {{{kind}_n}} | {{{kind}_rec}} % | {{{kind}_fa}} % | {{{kind}_miss}} | "
                    f"{{{kind}_k}} % / {{{kind}_eta}} % | {{{kind}_wall}} / {{{kind}_p90}} / {{{kind}_max}} s "
                    f"({{{kind}_cpu}} / {{{kind}_p90cpu}} / {{{kind}_maxcpu}} s CPU) | {{{kind}_cmp}} s"
                    f"{'' if f['compare_complete'] else ' (table incomplete)'} |\n")
        figures.update({f"{kind}_n": exact(f["draws"], "d"), f"{kind}_rec": exact(f["recovered_pct"], ".0f"),
                        f"{kind}_fa": exact(f["false_alarm_pct"], ".0f"), f"{kind}_miss": exact(f["misses"], "d"),
                        f"{kind}_k": exact(f["worst_k_pct"], pct(f["worst_k_pct"])),
                        f"{kind}_eta": exact(f["worst_eta_pct"], pct(f["worst_eta_pct"])),
                        f"{kind}_wall": timed(f["median_wall_s"], ".1f"), f"{kind}_cpu": on_cpu(f["median_cpu_s"], ".1f"),
                        f"{kind}_p90": timed(f["p90_wall_s"], ".1f"), f"{kind}_p90cpu": on_cpu(f["p90_cpu_s"], ".1f"),
                        f"{kind}_max": timed(f["max_wall_s"], ".1f"), f"{kind}_maxcpu": on_cpu(f["max_cpu_s"], ".1f"),
                        f"{kind}_cmp": timed(f["compare_max_wall_s"], ".0f")})
    m = run["machine"]
    return fill(
        f"Hard draws (`bench_identify.py --random --hard`, measured {m['date']} on {m['cores']} cores, one fit at a time; the "
        "load and the runs are stated in `benchmarks/results/identify_hard.txt`; [theory](../theory.md#verdict)): "
        "recovery within K' 1 % / loss factor 3 % (target ≥ 99 %), false alarms (\"poor fit\" on a recovered fit, "
        "≤ 2 %), misses (\"good fit\" outside 3 % / 10 %, 0), compare-models over the four drop-test families with "
        "a 60 s wall-time budget each (≤ 120 s with a full table; a family over its budget is listed \"not "
        "converged\"). A fit's CPU time counts the core's row threads on both cores, so on an idle machine it "
        "exceeds the wall time; wall times stretch with the machine's load, CPU times hardly.\n\n"
        "| family | draws | recovered | false alarms | misses | worst K' / loss factor RMS | wall time per fit: median "
        "/ 90th percentile / max (targets: 90th percentile ≤ 15 s, max ≤ 30 s on an idle machine) | compare-models, max |\n|---|---|---|---|---|---|---|---|\n" + "".join(rows), **figures)


def map_auto(stored: dict[str, Any]) -> Block:
    s = stored["study"]
    auto, paper = s["map_auto"], s["map_fit"]
    t4, camp = auto["table4"], auto["campaign"]
    return fill(
        "`auto` fits and cross-validates 35 candidate equations (14 for the stiffness, 21 for c/d): {t4_s} s on "
        f"Table 4, {{camp_s}} s on the {camp['n_tests']}-test campaign of the full study (`analysis/run_study.py`; "
        "CPU time on this machine; wall time {t4_w} s and {camp_w} s on it as loaded then), where it reaches {a_c} % / {a_ccv} % stiffness and {a_d} % / {a_dcv} % damping ratio RMS, "
        "fit / cross-validated, against the paper form's {p_c} % / {p_ccv} % and {p_d} % / {p_dcv} %.\n",
        t4_s=on_cpu(t4["cpu_s"], ".1f"), camp_s=on_cpu(camp["cpu_s"], ".1f"),
        t4_w=timed(t4["wall_s"], ".1f"), camp_w=timed(camp["wall_s"], ".1f"),
        a_c=exact(camp["stiffness_rms_error_pct"], ".2f"), a_ccv=exact(camp["stiffness_cv_rms_error_pct"], ".2f"),
        a_d=exact(camp["damping_ratio_rms_error_pct"], ".1f"), a_dcv=exact(camp["damping_ratio_cv_rms_error_pct"], ".1f"),
        p_c=exact(paper["stiffness_rms_error_pct"], ".2f"), p_ccv=exact(paper["stiffness_cv_rms_error_pct"], ".2f"),
        p_d=exact(paper["damping_ratio_rms_error_pct"], ".1f"), p_dcv=exact(paper["damping_ratio_cv_rms_error_pct"], ".1f"))


def _target_row(target: dict[str, Any], label: str, key: str, fmt: str, unit: str) -> tuple[str, Figure]:
    """A row of the targets table: the label, ``{key}`` for the figure, the limit and met or missed."""
    value, limit = target["value"], target["limit"]
    verdict = "met" if target["met"] else f"missed by {abs(value - limit):.1f} points" if unit else "missed"
    return (f"| {label} | {{{key}}}{unit} | {'≤' if target['kind'] == 'max' else '≥'} {limit:g}{unit} | {verdict} |\n",
            exact(value, fmt))


def study_targets(stored: dict[str, Any]) -> Block:
    s = stored["study"]
    targets = {t["target"]: t for t in s["targets"]}
    inside = s["servo_validation"]["inside"]
    rows = [
        ("campaign vs Table 4, stiffness rms %", "campaign vs Table 4, stiffness RMS", ".2f", " %"),
        ("campaign vs Table 4, damping ratio rms %", "campaign vs Table 4, damping ratio RMS", ".1f", " %"),
        ("map vs servo inside the hull, stiffness rms %", "map vs servo inside the tested hull, stiffness RMS", ".1f", " %"),
        ("map vs servo inside the hull, damping ratio rms %",
         "map vs servo inside the tested hull, damping ratio RMS (η: {eta} %, r: {r} %)", ".1f", " %"),
        ("loss factor 1 Hz / 30 Hz at 1.5 deg", "loss factor at 1 Hz / at 30 Hz (1.5°)", ".2f", ""),
        ("K' rise per decade, 1-30 Hz at 1.5 deg, %", "K' rise per decade, 1-30 Hz (1.5°)", ".1f", " %"),
        ("third harmonic at 1.5 deg, 30 Hz, % of fundamental", "third harmonic at 1.5°, 30 Hz, % of the fundamental",
         ".1f", " %"),
    ]
    template = "| target | figure | limit | |\n|---|---|---|---|\n"
    figures = {"eta": exact(inside["loss_factor_rms_deviation_pct"], ".1f"),
               "r": exact(inside["decay_ratio_rms_deviation_pct"], ".1f")}
    for i, (name, label, fmt, unit) in enumerate(rows):
        row, figures[f"t{i}"] = _target_row(targets[name], label, f"t{i}", fmt, unit)
        template += row
    # the core's speed as the benchmark measures it (best of 7 on CPU time: one thread, the wall time of an
    # idle machine; benchmarks/bench_core.py), like the table of Benchmarks
    rtf, limit = 1e3 / stored["core"]["figures"]["coupling_single_1s_cpu_ms"], targets[SPEED_TARGET]["limit"]
    template += (f"| core, 1 s at 38.4 kHz, single instance (`benchmarks/bench_core.py`, CPU time) | {{rtf}}× real time "
                 f"| ≥ {limit:g}× | {'met' if rtf >= limit else 'missed'} (this machine) |\n")
    return fill(template, rtf=on_cpu(rtf, ".0f"), **figures)


def study_results(stored: dict[str, Any]) -> Block:
    """The table of analysis/README.md: every comparison of the stored full study."""
    s = stored["study"]
    t4, sv, mf = s["table4"], s["servo_validation"], s["map_free_check"]
    figures: dict[str, Figure] = {}

    def f(key: str, value: float, fmt: str | None = None) -> str:
        figures[key] = exact(value, fmt or pct(value))
        return "{" + key + "}"

    def rms(key: str, part: dict[str, Any], name: str, with_max: bool = True) -> str:
        shown = f"{f(key, part[f'{name}_rms_deviation_pct'])} %"
        return shown + (f" ({f(key + 'x', part[f'{name}_max_deviation_pct'])} %)" if with_max else "")

    pre = s["table4_by_preload_nm"]
    preloads = " / ".join(pre)
    rows = [
        "| comparison | stiffness RMS (max) | damping ratio RMS (max) | target |\n|---|---|---|---|\n",
        f"| campaign vs Table 4 at each row's case and amplitude | {rms('cs', t4['campaign'], 'stiffness')} | "
        f"{rms('cd', t4['campaign'], 'damping')} | ≤ 5 %, ≤ 12 % |\n",
    ]
    if pre:
        rows.append(f"| campaign vs Table 4, per preload {preloads} N·m | "
                    + " / ".join(f(f"ps{i}", v["stiffness_rms_deviation_pct"], ".2f") for i, v in enumerate(pre.values()))
                    + " % | " + " / ".join(f(f"pd{i}", v["damping_rms_deviation_pct"], ".2f")
                                           for i, v in enumerate(pre.values())) + " % | no preload effect |\n")
    rows += [
        f"| map (eq. 19/20) vs Table 4 | {rms('ms', t4['map'], 'stiffness', False)} | "
        f"{rms('md', t4['map'], 'damping', False)} | — |\n",
        f"| map vs servo, inside the tested hull ({sv['inside']['n_points']} points) | {rms('is', sv['inside'], 'stiffness')}"
        f" | {rms('id', sv['inside'], 'damping')}; eta {f('ie', sv['inside']['loss_factor_rms_deviation_pct'])} %, r "
        f"{f('ir', sv['inside']['decay_ratio_rms_deviation_pct'])} % | ≤ 6 %, ≤ 7 % |\n",
        f"| map vs servo, inside the rectangle of the tested extremes ({sv['rectangle']['n_points']} points) | "
        f"{rms('rs', sv['rectangle'], 'stiffness', False)} | {rms('rd', sv['rectangle'], 'damping', False)} | — |\n",
        f"| map vs servo, outside the hull ({sv['outside']['n_points']} points) | "
        f"{rms('os', sv['outside'], 'stiffness', False)} | {rms('od', sv['outside'], 'damping', False)} | — |\n",
    ]
    if mf is not None:
        dvs, mvd = mf["decay_vs_servo"], mf["map_vs_decay"]
        rows += [
            f"| map-free: decays placed on the {dvs['n_points']} inside points vs the bench there | "
            f"{rms('fs', dvs, 'stiffness', False)} | {rms('fd', dvs, 'damping', False)}; eta "
            f"{f('fe', dvs['loss_factor_rms_deviation_pct'])} %, r {f('fr', dvs['decay_ratio_rms_deviation_pct'])} % | — |\n",
            f"| map vs those decays | {rms('vs', mvd, 'stiffness', False)} | {rms('vd', mvd, 'damping', False)} | — |\n",
        ]
    fit, rubber = s["map_fit"], s["coupling_figures"]
    rows.append(f"\nThe map fits the campaign within {f('fc', fit['stiffness_rms_error_pct'])} % (stiffness) and "
                f"{f('fdd', fit['damping_ratio_rms_error_pct'])} % (damping ratio) RMS ({s['tests_extracted']} of "
                f"{s['tests']} tests extracted). The coupling's loss factor at 1 Hz is "
                f"{f('lr', rubber['loss_factor_ratio'], '.2f')}x that at 30 Hz (1.5 deg), its third harmonic "
                f"{f('th', rubber['third_harmonic_pct'], '.1f')} % of the fundamental.\n")
    return fill("".join(rows), **figures)


def routes_table(stored: dict[str, Any], outside: bool = True) -> Block:
    """The route table (docs/routes.md): per route, RMS deviation from validate's servo points inside
    the paper map's hull, the identification's verdict and wall time (ratio to the campaign)."""
    r = stored["routes"]
    fig, m = r["figures"], r["machine"]
    first = next(iter(fig["routes"].values()))["inside"]["n_points"]
    figures: dict[str, Figure] = {}
    head = ("| route | K' RMS | loss factor RMS | d RMS |" + (" outside the hull: K' / loss factor RMS |" if outside else "")
            + " verdict, wall time (× the campaign) |\n|---|---|---|---|" + ("---|" if outside else "") + "---|\n")
    rows = []
    for i, (name, row) in enumerate(fig["routes"].items()):
        if not row["available"]:
            rows.append(f"| {name} | not available in this version |  |  |" + ("  |" if outside else "") + "  |\n")
            continue
        inside, out = row["inside"], row["outside"]
        for key, value in (("k", inside["stiffness_rms_pct"]), ("l", inside["loss_factor_rms_pct"]),
                           ("d", inside["damping_ratio_rms_pct"]), ("ok", out["stiffness_rms_pct"]),
                           ("ol", out["loss_factor_rms_pct"])):
            figures[f"{key}{i}"] = exact(value, pct(value))
        tail = "—"
        if "wall_s" in row:
            figures[f"w{i}"] = timed(row["wall_s"], ".0f")
            figures[f"x{i}"] = timed(row["wall_over_campaign"], ".1f")
            verdict = row["verdict"]
            if verdict == "poor fit" and row.get("error_over_noise") is not None:
                figures[f"n{i}"] = exact(row["error_over_noise"], ".0f")
                verdict = f"poor fit ({{n{i}}}× the noise)"
            tail = f"{verdict}, {{w{i}}} s ({{x{i}}}×)"
        rows.append(f"| {name} | {{k{i}}} % | {{l{i}}} % | {{d{i}}} % |" + (f" {{ok{i}}} % / {{ol{i}}} % |" if outside else "")
                    + f" {tail} |\n")
    figures["campaign"] = timed(fig["campaign_s"], ".1f")
    judged = [(i, name, row["agreement"]) for i, (name, row) in enumerate(fig["routes"].items()) if row.get("agreement")]
    en_block = ""
    if judged:  # E_n per servo row against the bench (ISO 13528), stored by bench_routes.py
        bench = judged[0][2]["bench_u95_rel"]
        s_in = fig.get("stated_inputs", {})
        en_rows = []
        for i, name, a in judged:
            cells = []
            for q, label in (("stiffness_nm_per_deg", "s"), ("damping_ratio", "d")):
                st = a["inside"][q]
                figures[f"e{label}a{i}"] = exact(st["agree"], "d")
                figures[f"e{label}n{i}"] = exact(st["n_points"], "d")
                figures[f"e{label}m{i}"] = exact(st["max_abs_en"], ".2f")
                cells.append(f"{{e{label}a{i}}} of {{e{label}n{i}}} (max \\|E_n\\| {{e{label}m{i}}})")
            en_rows.append(f"| {name} | " + " | ".join(cells) + " |\n")
        figures["bench"] = exact(100 * bench, "g")
        stated = ", ".join(f"{k.replace('_rel', '')} {100 * v:g} %" for k, v in s_in.items())
        en_block = ("\nAgreement with the bench (ISO 13528: E_n = (x_route − x_bench)/√(U_route² + U_bench²), "
                    "|E_n| ≤ 1 agrees), the servo rows inside the hull; the bench's U95 stated as {bench} %, the "
                    f"rig's inputs as standard uncertainties ({stated}; `bench_routes.py`'s STATED_FIGURES):\n\n"
                    "| route | stiffness: rows agreeing | damping ratio: rows agreeing |\n|---|---|---|\n"
                    + "".join(en_rows))
    plan = " (Table 2's cases and heights, one repeat, no preload: `--quick`)" if fig["plan"] == "quick" else " of Table 2"
    intro = (f"The {fig['tests']}-test campaign{plan}, {first} servo points inside the hull; measured {m['date']} on "
             f"{m['cores']} shared cores at load average {{lo}}–{{hi}}, which stretches wall times (the campaign itself "
             "took {campaign} s in the same run; compare the ratios).\n\n")
    loads = (m["load_average_start"], m["load_average_end"])
    figures.update(lo=timed(min(loads), ".1f"), hi=timed(max(loads), ".1f"))
    return fill(intro + head + "".join(rows) + en_block, **figures)


def at_scale(stored: dict[str, Any]) -> Block:
    """The report of a large campaign and the Dask campaign against its 450-test baseline."""
    rep, dask = stored["report"], stored["campaign_dask"]
    r, d = rep["figures"], dask["figures"]
    base, camp = d["baseline"], d["campaign"]
    rm, dm = rep["machine"], dask["machine"]
    n = d["tests"]
    def count(k: int) -> str:
        return f"{k:,}".replace(",", " ")

    scale = "" if n == d["target_tests"] else f", extrapolated from {count(n)} tests"
    return fill(
        f"Campaigns at scale (`bench_report.py --n {r['tests']}`, measured {rm['date']} at load average "
        "{r_lo}–{r_hi}; `bench_campaign.py --dask --n " + f"{n}`, measured {dm['date']} at load average " + "{d_lo}–{d_hi}; "
        f"{dm['cores']} shared cores):\n\n"
        "| figure | measured | target |\n|---|---|---|\n"
        f"| report of {count(r['tests'])} tests: written | " + "{r_write} s ({r_ratio}× extracting its logs again) | ≤ 60 s |\n"
        "| its size, page and side files | {r_mb} MB | ≤ 40 MB |\n"
        "| opened in headless Chromium (table and first decay plot drawn) | {r_open} s | ≤ 10 s |\n"
        f"| Dask, 2 workers: {count(n)} tests | " + "{d_wall} s ({d_ms} ms per test; 450 tests: {b_ms} ms per test) | |\n"
        "| per-test wall time, against 450 tests on the same cluster | {d_ratio} (CPU {d_cpu}) | ≤ 1.15 |\n"
        f"| {count(d['target_tests'])} tests at that rate{scale} (at the load above) | " + "{d_full} min "
        "| ≤ 12 min unloaded |\n"
        "| disk per test (logs and records) | {d_kb} kB | ≤ 90 kB |\n"
        "| peak memory after 450 tests, then after all: client (with the scheduler) | {b_cm} MB, {d_cm} MB | "
        "bounded |\n| the same, largest worker | {b_wm} MB, {d_wm} MB | bounded |\n",
        r_lo=timed(min(rm["load_average_start"], rm["load_average_end"]), ".1f"),
        r_hi=timed(max(rm["load_average_start"], rm["load_average_end"]), ".1f"),
        d_lo=timed(min(dm["load_average_start"], dm["load_average_end"]), ".1f"),
        d_hi=timed(max(dm["load_average_start"], dm["load_average_end"]), ".1f"),
        r_write=timed(r["write_s"], ".1f"), r_ratio=timed(r["write_s"] / r["baseline_s"], ".2f"),
        r_mb=timed(r["size_mb"], ".1f"), r_open=timed(r["open_s"], ".1f"),
        d_wall=timed(camp["wall_s"], ".0f"), d_ms=timed(1e3 * camp["wall_s"] / camp["tests"], ".1f"),
        b_ms=timed(1e3 * base["wall_s"] / base["tests"], ".1f"), d_ratio=timed(d["per_test_ratio"], ".2f"),
        d_cpu=on_cpu(d["per_test_cpu_ratio"], ".2f"), d_full=timed(d["wall_s_for_target_tests"] / 60, ".1f"),
        d_kb=on_cpu(camp["disk_kb_per_test"], ".1f"), d_cm=timed(camp["client_peak_mb"], ".0f"),
        d_wm=timed(camp["worker_peak_mb"], ".0f"), b_cm=timed(base["client_peak_mb"], ".0f"),
        b_wm=timed(base["worker_peak_mb"], ".0f"))


def uncertainty_coverage(stored: dict[str, Any]) -> Block:
    """The coverage of the model route's 95 % intervals (docs/guide/uncertainty.md): the package's
    identification (bench_uncertainty_route.py) and the closed-form route (bench_uncertainty_coverage.py)."""
    route, closed = stored["uncertainty_route"], stored["uncertainty_coverage"]
    r, c = route["figures"], closed["figures"]
    def share(v: float) -> Figure:
        return exact(100 * v, ".1f")

    dom = r["dominant_storage_stiffness"]
    top = max(dom, key=dom.get)
    return fill(
        "| route of the campaigns | campaigns (drops each) | K' covered | loss factor covered | fit-only: K' / loss factor "
        "| CPU per campaign |\n|---|---|---|---|---|---|\n"
        f"| identified from the drops, {r['family']}, the virtual bench at {r['servo_frequency_hz']:g} Hz, every input "
        "| {rn} ({rd}) | {rk} % | {re} % | {rkf} % / {ref} % | {rcpu} s |\n"
        "| closed forms of a linear coupling, J and the clock | {cn} ({cd}) | {ck} % | {ce} % | {ckf} % / {cef} % "
        "| {ccpu} s |\n\n"
        "Target: 95 % ± 2.5 % with the inputs (binomial standard deviation {rstd} % and {cstd} %); measured "
        f"{route['machine']['date']} and {closed['machine']['date']}. The identified route's K' is dominated by "
        f"`{top}` in {{rdom}} of the campaigns; its loss factor by the lever length (the initial rate L·∫F dt/J "
        "sets the decay's amplitude) in {rlev} (`python analysis/readme_figures.py --render-only` writes this "
        "table from benchmarks/results/uncertainty_route.json and uncertainty_coverage.json).\n",
        rn=exact(r["campaigns"], "d"), rd=exact(r["drops_per_campaign"], "d"), rk=share(r["coverage_storage_stiffness"]),
        re=share(r["coverage_loss_factor"]), rkf=share(r["coverage_storage_stiffness_fit_only"]),
        ref=share(r["coverage_loss_factor_fit_only"]), rcpu=on_cpu(r["cpu_s_per_campaign"], ".2f"),
        cn=exact(c["campaigns"], "d"), cd=exact(c["drops_per_campaign"], "d"), ck=share(c["coverage_storage_stiffness"]),
        ce=share(c["coverage_loss_factor"]), ckf=share(c["coverage_storage_stiffness_fit_only"]),
        cef=share(c["coverage_loss_factor_fit_only"]), ccpu=on_cpu(c["cpu_s_per_campaign"], ".3f"),
        rstd=exact(100 * r["binomial_std_at_95pct"], ".2f"), cstd=exact(100 * c["binomial_std_at_95pct"], ".2f"),
        rdom=exact(dom[top], "d"), rlev=exact(r["dominant_loss_factor"].get("lever_length_m", 0), "d"))


def _loads(m: dict[str, Any]) -> dict[str, Figure]:
    return {"lo": timed(min(m["load_average_start"], m["load_average_end"]), ".1f"),
            "hi": timed(max(m["load_average_start"], m["load_average_end"]), ".1f")}


def fresh_table(stored: dict[str, Any]) -> Block:
    """The commands as a user meets them (fresh processes), against the previous release in the same run."""
    run = stored["fresh"]
    f, m = run["figures"], run["machine"]
    base = f["baseline_label"]
    rows, figures = [], {}

    def compared(key: str, what: str, target: str) -> None:
        """A command both versions run: each one's wall and CPU time, the ratio."""
        if f"{key}_wall_s" not in f:  # a figure an older run of the benchmark did not measure
            return
        rows.append(f"| {what} | {{{key}_w}} s ({{{key}_c}} s CPU) | {{{key}_bw}} s ({{{key}_bc}} s CPU) "
                    f"| {{{key}_r}}× ({{{key}_rc}}× on CPU) | {target} |\n")
        figures.update({f"{key}_w": timed(f[f"{key}_wall_s"], ".2f"), f"{key}_c": on_cpu(f[f"{key}_cpu_s"], ".2f"),
                        f"{key}_bw": timed(f[f"{key}_baseline_wall_s"], ".2f"),
                        f"{key}_bc": on_cpu(f[f"{key}_baseline_cpu_s"], ".2f"),
                        f"{key}_r": timed(f[f"{key}_speed_up_wall"], ".1f"), f"{key}_rc": on_cpu(f[f"{key}_speed_up_cpu"], ".1f")})

    compared("import", "`python -c \"from droptower.extract import extract_file\"`", "≤ 0.5 s")
    compared("extract", "`droptower extract ONE_FILE --out r.csv` (one 10 000-sample log)", "≤ 1.0 s")
    compared("campaign", "`droptower campaign --out DIR --workers 2` (Table 2, 450 tests)", "≤ 5 s")
    if "campaign_large_wall_s" in f:
        n = f"{f['campaign_large_tests']:,}".replace(",", " ")
        rows.append(f"| the same campaign, {n} tests | " + "{large_w} s ({large_c} s CPU): {large_r}× the 450-test run "
                    "(CPU {large_rc}×) | | | ≤ 10× |\n")
        figures.update({"large_w": timed(f["campaign_large_wall_s"], ".1f"), "large_c": on_cpu(f["campaign_large_cpu_s"], ".1f"),
                        "large_r": timed(f["campaign_large_over_450"], ".1f"),
                        "large_rc": on_cpu(f["campaign_large_over_450_cpu"], ".1f")})
    compared("map", "`droptower map DIR --plot DIR/map` (the README's first command, its second step; 450 tests)", "")
    rows.append("| core, `rapp2022_nr60` driven 1 s at 38.4 kHz (1 deg, 10 Hz), fresh process | {core_rt}× real time "
                "({core_rtc}× on CPU time) | {core_brt}× ({core_brtc}×) | | ≥ 200× |\n")
    figures.update({"core_rt": timed(f["core_real_time_factor"], ".0f"), "core_rtc": on_cpu(f["core_real_time_factor_cpu"], ".0f"),
                    "core_brt": timed(f["core_baseline_real_time_factor"], ".0f"),
                    "core_brtc": on_cpu(f["core_baseline_real_time_factor_cpu"], ".0f")})
    if "route_wall_s" in f:
        model, tests = f["route_model"], f["route_tests"]
        route = stored["routes"]["figures"]["routes"][f"model-based map, {model}"]["inside"]
        rows.append(f"| the model route: `droptower identify --from-drop-tests DIR --model {model}` ({tests} tests) | "
                    "{route_w} s ({route_c} s CPU), " + f"{f['route_verdict']}; " + "K' {route_k} %, loss factor "
                    "{route_eta} % RMS against the bench at " + f"{f['route_inside_points']} servo points inside the hull "
                    "(in process, `bench_routes.py`: {routes_k} %, {routes_eta} %) | " + f"fits no {model} to drop tests "
                    "| | ≤ 30 s |\n")
        figures.update({"route_w": timed(f["route_wall_s"], ".1f"), "route_c": on_cpu(f["route_cpu_s"], ".1f"),
                        "route_k": exact(f["route_inside_stiffness_rms_pct"], ".2f"),
                        "route_eta": exact(f["route_inside_loss_factor_rms_pct"], ".2f"),
                        "routes_k": exact(route["stiffness_rms_pct"], ".2f"),
                        "routes_eta": exact(route["loss_factor_rms_pct"], ".2f")})
    compared("route_template", "the template route, which both fit: `droptower identify --from-drop-tests DIR --model "
                               "template --template rapp2022_nr60` (450 tests)", "")
    return fill(
        f"Fresh processes, as a user runs the commands (`bench_fresh.py --large`, measured {m['date']} on "
        f"{m['cores']} shared cores at load average " + "{lo}–{hi}): best-of-N wall time and the CPU time of the "
        f"process and its workers, against the previous release ({base}, `{f['baseline_ref']}`) run the same way, "
        "interleaved, in the same run.\n\n"
        f"| command | this version | {base} | speed-up | target |\n|---|---|---|---|---|\n" + "".join(rows),
        **_loads(m), **figures)


def campaign_time(stored: dict[str, Any]) -> Block:
    """One sentence of docs/guide/campaign.md: the README's campaign as a fresh command."""
    run = stored["fresh"]
    return fill("The 450 tests of Table 2 take {wall} s on two cores as a fresh `droptower campaign --workers 2` "
                f"(measured {run['machine']['date']} at load average " + "{lo}–{hi}; [benchmarks](../benchmarks.md)).\n",
                wall=timed(run["figures"]["campaign_wall_s"], ".1f"), **_loads(run["machine"]))


def zerodim20_times(stored: dict[str, Any]) -> Block:
    """zerodim20's fit times on stepped sines (docs/guide/identification.md)."""
    z = stored["identify"]["figures"]["zerodim20"]
    good, far = z["stepped sines (9 bench records, 0.3/1/2 deg x 2/8/20 Hz)"], \
        z["test types whose zerodim6 branch stages end far off (ranking test's draw)"]
    m = stored["identify"]["machine"]
    return fill(
        f"Measured (`bench_identify.py --zerodim20`, {m['date']}, load average " + "{lo}–{hi} on the 2 cores): "
        "`zerodim20` on the virtual bench's stepped sines of a random zerodim6-type coupling (9 records, 0.3/1/2 deg "
        "at 2/8/20 Hz, 25 s at 2048 Hz, 0.5 % noise) {cmp} s per fit in `compare-models` ({cmp_c} s CPU), {alone} s "
        "alone ({alone_c} s CPU; its zerodim6 start included), a good fit at the noise; on records whose branch "
        "stages end far from the optimum (the ranking test's first zerodim6 draw) {far} s alone.\n",
        cmp=timed(good["zerodim20_wall_s"], ".1f"), cmp_c=on_cpu(good["zerodim20_cpu_s"], ".1f"),
        alone=timed(good["zerodim20_alone_wall_s"], ".1f"), alone_c=on_cpu(good["zerodim20_alone_cpu_s"], ".1f"),
        far=timed(far["zerodim20_alone_wall_s"], ".1f"), **_loads(m))


def random_fits(path: Path | None = None) -> dict[str, list[dict[str, float]]]:
    """Per family, the fits of ``bench_identify.py --random`` as stored in its text output
    (``benchmarks/results/identify_random.txt``: one line per coupling, ``key value`` pairs)."""
    fits: dict[str, list[dict[str, float]]] = {}
    for line in (path or BENCH_RESULTS / "identify_random.txt").read_text().splitlines():
        match = re.match(r"\s+(\w+) #\d+: (.*)", line)
        if match is None:
            continue
        pairs = dict(item.strip().split(" ", 1) for item in match.group(2).split(","))
        numbers = {}
        for key, value in pairs.items():
            try:
                numbers[key] = float(value)
            except ValueError:  # a verdict, a flag
                pass
        fits.setdefault(match.group(1), []).append(numbers)
    return fits


def identify_random_times(stored: dict[str, Any]) -> Block:
    """Times per fit of the randomised acceptance (docs/guide/identification.md), from its stored output."""
    import statistics

    fits = random_fits()
    medians = [statistics.median(f["drop_cpu_s"] for f in rows) for rows in fits.values()]
    slowest = max(((f["drop_wall_s"], family) for family, rows in fits.items() for f in rows))
    servo = [statistics.median(f["servo_wall_s"] for f in rows if "servo_wall_s" in f) for rows in fits.values()]
    servo_max = max(f["servo_wall_s"] for rows in fits.values() for f in rows if "servo_wall_s" in f)
    return fill(f"Time per drop-test fit (`benchmarks/results/identify_random.txt`): median {{lo}}–{{hi}} s CPU by "
                f"family, the slowest {{slow}} s wall ({slowest[1]}); servo fits: median ≤ {{servo}} s, the slowest "
                "{servo_max} s wall.\n",
                lo=on_cpu(min(medians), ".1f"), hi=on_cpu(max(medians), ".1f"), slow=timed(slowest[0], ".0f"),
                servo=timed(max(servo), ".1f"), servo_max=timed(servo_max, ".0f"))


def refit_time(stored: dict[str, Any]) -> Block:
    """What one refit of a model-based route costs (docs/routes.md), from the stored route benchmark."""
    routes = [r for name, r in stored["routes"]["figures"]["routes"].items()
              if name.startswith("model-based") and r.get("available") and "wall_s" in r]
    walls = [r["wall_s"] for r in routes]
    return fill("Each refit is a whole nonlinear identification, {lo_s}–{hi_s} s on the Table-2 campaign "
                f"(the {len(walls)} model-based routes of `bench_routes.py`, measured "
                f"{stored['routes']['machine']['date']}), so the bootstrap takes hours.\n",
                lo_s=timed(min(walls), ".0f"), hi_s=timed(max(walls), ".0f"))


def report_size(stored: dict[str, Any]) -> Block:
    """The size of a campaign's report (docs/guide/report.md), from the stored report benchmark."""
    r = stored["report"]
    n = f"{r['figures']['tests']:,}".replace(",", " ")
    return fill(f"The page with its side files measured {{mb}} MB for a campaign of {n} tests (`bench_report.py "
                f"--n {r['figures']['tests']}`, {r['machine']['date']}; [benchmarks](../benchmarks.md)).\n",
                mb=timed(r["figures"]["size_mb"], ".1f"))


def core_step(stored: dict[str, Any]) -> Block:
    """The coupling kernel's cost per step (docs/benchmarks.md), from bench_core's CPU time."""
    core = stored["core"]
    from droptower.rates import RIG_SAMPLE_RATE_HZ

    cpu_ms = core["figures"]["coupling_single_1s_cpu_ms"]  # 1 s at the rig's sample rate
    return fill("What remains is the coupling kernel itself in flight (about {ns} ns per step for "
                f"`{core['figures']['coupling']}`, " + "~{test_ms} ms per 0.25 s test: `bench_core.py`'s CPU time, "
                f"measured {core['machine']['date']}), writing and reading the logs, and the fixed costs of a run (the "
                "plan, worker start-up, the results table).\n",
                ns=on_cpu(cpu_ms * 1e6 / RIG_SAMPLE_RATE_HZ, ".0f"), test_ms=on_cpu(cpu_ms / 4, ".1f"))


def report_at_scale(stored: dict[str, Any]) -> Block:
    """The report of 4 500 tests (docs/campaigns_at_scale.md), from bench_report.py's stored run."""
    r, m = stored["report"]["figures"], stored["report"]["machine"]
    n = f"{r['tests']:,}".replace(",", " ")
    return fill(f"Measured {m['date']} on the {m['cores']} cores at load average " + "{lo}–{hi}, on a "
                f"{n}-test campaign: " + "{mb} MB; written in {write} s, {ratio} times reading back and extracting "
                "the same logs in the same run ({base} s in one process, {per_log} ms per log); opened in {open} s; "
                "a test of the last side file drawn in {demand} s.\n",
                mb=timed(r["size_mb"], ".1f"), write=timed(r["write_s"], ".1f"),
                ratio=timed(r["write_s"] / r["baseline_s"], ".2f"), base=timed(r["baseline_s"], ".1f"),
                per_log=timed(1e3 * r["baseline_s"] / r["tests"], ".1f"), open=timed(r["open_s"], ".1f"),
                demand=timed(r["on_demand_s"], ".2f"), **_loads(m))


def compile_time(stored: dict[str, Any]) -> Block:
    """numba's cold compilation of every kernel (docs/getting-started.md), from bench_compile.py."""
    run = stored["compile"]
    f = run["figures"]
    return fill(f"Compiling all {len(f['kernels_cpu_s'])} top-level kernels from an empty cache costs " + "{cpu} s of "
                "CPU once ({wall} s wall at load average {lo}–{hi}; `benchmarks/bench_compile.py`, measured "
                f"{run['machine']['date']}).\n",
                cpu=on_cpu(f["total_cpu_s"], ".0f"), wall=timed(f["total_wall_s"], ".0f"), **_loads(run["machine"]))


def identify_random_accuracy(stored: dict[str, Any]) -> Block:
    """The randomised acceptance's outcome (docs/guide/identification.md), from its stored output
    (``benchmarks/results/identify_random.txt``): successes, the worst fits by family, the servo's."""
    fits = random_fits()
    flags: dict[str, list[dict[str, str]]] = {}  # the verdicts and success flags random_fits leaves out
    for line in (BENCH_RESULTS / "identify_random.txt").read_text().splitlines():
        if match := re.match(r"\s+(\w+) #\d+: (.*)", line):
            flags.setdefault(match.group(1), []).append(
                dict(item.strip().split(" ", 1) for item in match.group(2).split(",")))
    figures: dict[str, Figure] = {}
    rows = []
    n_drop = n_servo = total = 0
    for family, rows_ in fits.items():
        ok_d = sum(f["drop_ok"] == "True" for f in flags[family])
        ok_s = sum(f.get("servo_ok") == "True" for f in flags[family])
        poor = sum(f["drop_verdict"] == "poor fit" for f in flags[family])
        n_drop, n_servo, total = n_drop + ok_d, n_servo + ok_s, total + len(rows_)
        figures.update({f"{family}_n": exact(len(rows_), "d"), f"{family}_d": exact(ok_d, "d"),
                        f"{family}_s": exact(ok_s, "d"), f"{family}_p": exact(poor, "d"),
                        f"{family}_k": exact(100 * max(f["drop_k"] for f in rows_), ".2f"),
                        f"{family}_e": exact(100 * max(f["drop_eta"] for f in rows_), ".2f")})
        rows.append(f"| {family} | {{{family}_d}} of {{{family}_n}} | {{{family}_s}} of {{{family}_n}} "
                    f"| {{{family}_k}} % / {{{family}_e}} % | {{{family}_p}} |\n")
    holdout = max(f["servo_holdout"] for rows_ in fits.values() for f in rows_ if "servo_holdout" in f)
    return fill("Measured on the stored run (`benchmarks/results/identify_random.txt`), success: K' ≤ 3 % and loss "
                "factor ≤ 10 % RMS for a drop-test fit, hold-out nRMSE ≤ 1 % for a servo fit:\n\n"
                "| family | drop-test fits succeeding | servo fits succeeding | worst drop-test K' / loss factor RMS "
                "| drop-test fits the verdict calls \"poor fit\" |\n|---|---|---|---|---|\n" + "".join(rows)
                + "\nIn all {n_drop} of {total} drop-test and {n_servo} of {total} servo fits succeed; worst servo "
                "hold-out nRMSE {holdout} % (noise 0.5 %).\n",
                n_drop=exact(n_drop, "d"), n_servo=exact(n_servo, "d"), total=exact(total, "d"),
                holdout=exact(100 * holdout, ".2f"), **figures)


def map_table4(stored: dict[str, Any]) -> Block:
    """The paper's form and ``auto`` on Table 4 (docs/guide/map.md): the paper's form as
    tests/test_maps.py stores it, ``auto`` as the stored full study fitted it."""
    paper = stored["tests"]["test_maps"]["test_table4_fit_reaches_the_global_minimum"]
    auto = stored["study"]["map_auto"]["table4"]
    return fill(
        "| form | coefficients | stiffness RMS fit / cross-validated | damping ratio RMS fit / cross-validated | "
        "identifiable |\n|---|---|---|---|---|\n"
        "| `paper` (eq. 19, 20) | 13 | {p_c} % / {p_ccv} % | {p_d} % / {p_dcv} % | no: k9 at its bound, k12, k13 > 50 %, "
        "k5, k7 not unique |\n"
        "| `auto` (chooses `velocity`'s terms) | 10 | {a_c} % / {a_ccv} % | {a_d} % / {a_dcv} % | yes, every coefficient |\n"
        "\n`paper`: `tests/test_maps.py`'s stored figures; `auto`: the stored full study (`analysis/run_study.py`).\n",
        p_c=exact(paper["stiffness_rms_error_pct"], ".2f"), p_ccv=exact(paper["stiffness_cv_rms_error_pct"], ".2f"),
        p_d=exact(paper["damping_ratio_rms_error_pct"], ".2f"), p_dcv=exact(paper["damping_ratio_cv_rms_error_pct"], ".1f"),
        a_c=exact(auto["stiffness_rms_error_pct"], ".2f"), a_ccv=exact(auto["stiffness_cv_rms_error_pct"], ".2f"),
        a_d=exact(auto["damping_ratio_rms_error_pct"], ".2f"), a_dcv=exact(auto["damping_ratio_cv_rms_error_pct"], ".2f"))


def map_nested(stored: dict[str, Any]) -> Block:
    """``auto``'s choice validated by nested cross-validation on Table 4 (docs/guide/map.md), from
    the map command's stored output (:data:`NESTED_MAP`)."""
    m = stored["map_nested"]
    nested, fit = m["nested_cross_validation"], m["fit"]
    folds = int(re.search(r"(\d+) folds", nested["outer"]).group(1))
    choice, times = re.fullmatch(r"(.*) \((\d+)x\)", nested["chosen"]).groups()
    stiffness, ratio = (" + ".join(f"`{t}`" for t in part.split(" + ")) for part in choice.split(" | "))
    return fill("On Table 4 (`droptower map rapp2022_table4 --form auto --nested-cv --json`, stored in "
                "`analysis/results/table4_map_nested.json`) {times} of the {folds} folds choose the same terms, "
                f"{stiffness} for the stiffness and {ratio} for c/d (`velocity`'s), by its inner error among 5 identifiable "
                "stiffness and 10 identifiable c/d candidates; the nested cross-validated errors are {ns} % stiffness and "
                "{nd} % damping ratio (RMS), the map's own cross-validated errors {cs} % and {cd} %.\n",
                times=exact(int(times), "d"), folds=exact(folds, "d"),
                ns=exact(nested["stiffness_rms_error_pct"], ".2f"), nd=exact(nested["damping_ratio_rms_error_pct"], ".2f"),
                cs=exact(fit["stiffness_cv_rms_error_pct"], ".2f"), cd=exact(fit["damping_ratio_cv_rms_error_pct"], ".2f"))


def study_random_angle(stored: dict[str, Any]) -> Block:
    """The reference coupling's one-step torque change on random motion (docs/study.md), as
    tests/test_reference_coupling_histories.py stores it (two seeded draws)."""
    draws = [v for k, v in stored["tests"]["test_reference_coupling_histories"].items()
             if k.startswith("test_torque_is_continuous_on_random_motion")]
    return fill(f"On a band-limited random angle (1-50 Hz, RMS 0.5 deg; {len(draws)} seeded draws, "
                "`tests/test_reference_coupling_histories.py`'s stored figures) its largest one-step torque change is "
                "at most {fine} % of the RMS torque at 153.6 kHz ({coarse} % at 38.4 kHz: it shrinks with the step).\n",
                fine=exact(100 * max(d["jump_over_rms_at_153600_hz"] for d in draws), ".2f"),
                coarse=exact(100 * max(d["jump_over_rms_at_38400_hz"] for d in draws), ".2f"))


def study_case_cv(stored: dict[str, Any]) -> Block:
    """Table 4 cross-validated by lever case (docs/study.md), from the stored calibration
    (``analysis/results/nr60_cross_validation.csv``, ``calibrate_nr60.py``)."""
    import csv

    with (STUDY_RESULTS / "nr60_cross_validation.csv").open() as fh:
        rows = sorted(csv.DictReader(fh), key=lambda r: int(r["held_out_case"]))
    figures = {f"s{i}": exact(float(r["stiffness_rms_pct"]), ".1f") for i, r in enumerate(rows)}
    figures |= {f"d{i}": exact(float(r["damping_rms_pct"]), ".1f") for i, r in enumerate(rows)}
    cases = " / ".join(r["held_out_case"] for r in rows)
    return fill(f"Table 4 cross-validated by lever case (cases {cases}, each predicted by the calibration on the two "
                "other cases; `analysis/results/nr60_cross_validation.csv`): stiffness RMS "
                + " / ".join(f"{{s{i}}}" for i in range(len(rows))) + " %, damping "
                + " / ".join(f"{{d{i}}}" for i in range(len(rows))) + " %. The error by case is in `analysis/README.md`.\n",
                **figures)


def study_tradeoff(stored: dict[str, Any]) -> Block:
    """The calibration's trade-off between Table 4's decays and the bench (docs/study.md): the stored
    study's map-free check and the stored candidate calibrated to meet the bench."""
    import csv

    free = stored["study"]["map_free_check"]["decay_vs_servo"]
    with (STUDY_RESULTS / "nr60_candidates.csv").open() as fh:
        servo_heavy = next(r for r in csv.DictReader(fh) if r["candidate"] == "joint_servo_heavy")
    return fill("So a coupling that reproduces Table 4's decays has a bench damping well below them (the stored "
                "study's map-free check, decays vs bench at the same points: {s} % in stiffness, {d} % in d, RMS), "
                "and the candidate calibrated to meet the bench (`joint_servo_heavy` in "
                "`analysis/results/nr60_candidates.csv`: map vs servo {js} % in d) misses Table 4's damping by "
                "{jt} % RMS. The preset is the candidate that misses the fewest targets.\n",
                s=exact(free["stiffness_rms_deviation_pct"], ".1f"), d=exact(free["damping_rms_deviation_pct"], ".0f"),
                js=exact(float(servo_heavy["servo_inside_damping_rms_pct"]), ".1f"),
                jt=exact(float(servo_heavy["table4_damping_rms_pct"]), ".0f"))


def uncertainty_cost(stored: dict[str, Any]) -> Block:
    """What the uncertainty budgets of a campaign cost (docs/guide/uncertainty.md), from the stored
    ``bench_uncertainty.py`` run (CPU times against the campaign's own extraction)."""
    run = stored["uncertainty"]
    f, m = run["figures"], run["machine"]
    ms = 1e3 / f["tests"]
    return fill(
        f"On the Table-2 campaign ({f['tests']} drops, J 1 %, laser radius and calibration, torque calibration, clock; "
        f"`benchmarks/bench_uncertainty.py`, measured {m['date']}, CPU times, stored in "
        "`benchmarks/results/uncertainty.json`) the GUM alone costs {gum_ms} ms a drop, {gum_r} % of the extraction; "
        "Monte Carlo on every drop {mc_ms} ms a drop, {mc_r}× the extraction. `campaign_budgets` ran Monte Carlo on "
        "{mc_n} drops, the budgets cost {cb_r}× the campaign's extraction, and U95 differed from Monte Carlo on the "
        "drop itself by at most {diff} %.\n",
        gum_ms=on_cpu(f["gum_only_cpu_s"] * ms, ".2f"), gum_r=on_cpu(100 * f["ratio_gum_to_extraction"], ".0f"),
        mc_ms=on_cpu(f["monte_carlo_every_drop_cpu_s_scaled"] * ms, ".0f"),
        mc_r=on_cpu(f["ratio_monte_carlo_every_drop_to_extraction"], ".1f"), mc_n=exact(f["drops_with_monte_carlo"], "d"),
        cb_r=on_cpu(f["ratio_campaign_budgets_to_extraction"], ".2f"),
        diff=exact(100 * f["max_relative_difference_U95_vs_monte_carlo_on_the_drop"], ".1f"))


def uncertainty_drops(stored: dict[str, Any]) -> Block:
    """The 95 % intervals' coverage on virtual drops of known truth (docs/guide/uncertainty.md), as
    tests/test_uncertainty_coverage.py stores it."""
    c = stored["tests"]["test_uncertainty_coverage"]["test_the_coverage_is_stored"]
    return fill("On 1000 virtual drops whose rig (J at 1 %, the clock at 100 ppm, the laser's radius ±1 mm and "
                "calibration, the torque calibration) is drawn from its stated uncertainties, synthesised with the drawn "
                "rig and extracted with the nominal one, the 95 % intervals hold the true stiffness in {k} % and the true "
                "frequency in {f} % of the drops; the fit's intervals alone, in {kf} % and {ff} % "
                "(`tests/test_uncertainty_coverage.py`'s stored figures).\n",
                k=exact(100 * c["with_inputs_stiffness_nm_per_rad"], ".1f"),
                f=exact(100 * c["with_inputs_frequency_hz"], ".1f"),
                kf=exact(100 * c["fit_only_stiffness_nm_per_rad"], ".1f"),
                ff=exact(100 * c["fit_only_frequency_hz"], ".1f"))


def first_cycle_figures(stored: dict[str, Any]) -> Block:
    """The first cycle's two mechanisms on the reference coupling (docs/theory.md#first-cycle), as
    tests/test_nr60_calibration.py stores them (Table 2's 30 fast-loop decays against the bench)."""
    t = stored["tests"]["test_nr60_calibration"]["test_decays_against_the_bench_at_their_own_points"]
    pc = {k: exact(100 * v, ".1f" if abs(100 * v) < 10 else ".0f") for k, v in t.items() if not k.startswith("creep_m")}
    return fill(
        "Measured on the reference coupling's 30 decays (Table 2's three lever cases × its heights) against the bench at "
        "each decay's own "
        "amplitude and frequency (`tests/test_nr60_calibration.py`'s stored figures), damping ratio over the bench's, "
        "RMS: the coupling reads {read_over_bench_rms} % above the bench; its network alone (spring and filler "
        "network) {network_over_bench_rms} %, which the loop-span balance predicts within {network_span_error_rms} %; "
        "the balance alone puts the coupling {span_over_bench_rms} % above the bench. The creep factor of its linear "
        "part (spring and matrix branch dropped from the same heights: its reading over its bench) is {creep_min}–"
        "{creep_max}; the balance times the creep factor gives every decay's reading within {predicted_error_rms} % "
        "(−{neg} to +{predicted_error_max} %), while either mechanism alone misses by {span_alone_error_rms} % "
        "(the balance) or {creep_alone_error_rms} % (the creep).\n",
        creep_min=exact(t["creep_min"], ".2f"), creep_max=exact(t["creep_max"], ".2f"),
        neg=exact(-100 * t["predicted_error_min"], ".1f"), **pc)


def filled_rubber_run(path: Path | None = None) -> dict[str, Any]:
    """The newest run in ``benchmarks/results/identify_filled_rubber.txt`` (the file's first block,
    ``bench_identify.py --filled-rubber``): its date and load, the Table-2 fits, each drawn coupling."""
    lines = (path or BENCH_RESULTS / "identify_filled_rubber.txt").read_text().splitlines()
    end = next(i for i, line in enumerate(lines) if i and not line.strip())
    block = lines[:end]
    date = re.search(r"\d{4}-\d\d-\d\d", block[0]).group()
    load = float(re.search(r"load average ([\d.]+) at the start", "\n".join(block)).group(1))
    number = r"([\d.]+)"
    run: dict[str, Any] = {"date": date, "load": load, "draws": {}, "worst": {}}
    for line in block:
        text_ = line.strip()
        if m := re.match(r"Table 2 \((\d+) tests", text_):
            run["tests"] = int(m.group(1))
        elif m := re.match(r"paper's map \(eq\. 19/20\): (\d+) points, K' " + number + r" % RMS, loss factor " + number,
                           text_):
            run["points"], run["paper_k"], run["paper_eta"] = int(m.group(1)), float(m.group(2)), float(m.group(3))
        elif m := re.match(r"identify (\w+): K' " + number + r" % RMS, loss factor " + number + r" % RMS .*?; (good|poor) "
                           r"fit \(" + number + r" x the noise\); " + number + r" s wall / " + number + r" s CPU, (\d+) "
                           r"evaluations", text_):
            run[m.group(1)] = {"k": float(m.group(2)), "eta": float(m.group(3)), "verdict": f"{m.group(4)} fit",
                               "noise": float(m.group(5)), "wall_s": float(m.group(6)), "cpu_s": float(m.group(7)),
                               "evaluations": int(m.group(8))}
        elif m := re.match(r"(\w+) #(\d+): K' " + number + r" %, loss factor " + number + r" % RMS; (good|poor) fit \("
                           + number + r" x the noise\)", text_):
            run["draws"].setdefault(m.group(1), []).append(
                {"k": float(m.group(3)), "eta": float(m.group(4)), "verdict": f"{m.group(5)} fit", "noise": float(m.group(6))})
        elif m := re.match(r"(\w+): K' " + number + r" %, loss factor " + number + r" % RMS; (good|poor) fit \("
                           + number + r" x the noise\)", text_):
            run["draws"].setdefault(m.group(1), []).append(
                {"k": float(m.group(2)), "eta": float(m.group(3)), "verdict": f"{m.group(4)} fit", "noise": float(m.group(5))})
        elif m := re.match(r"(\w+): (\d+)/(\d+) within K' 5 % and loss factor 10 % RMS; worst K' " + number
                           + r" %, loss factor " + number + " %", text_):
            run["worst"][m.group(1)] = {"met": int(m.group(2)), "draws": int(m.group(3)), "k": float(m.group(4)),
                                        "eta": float(m.group(5))}
    return run


def filled_rubber(stored: dict[str, Any]) -> Block:
    """The `filled_rubber` family's drop-test accuracy (docs/theory.md), from the newest run stored in
    ``benchmarks/results/identify_filled_rubber.txt``."""
    run = filled_rubber_run()
    fr, tp, w = run["filled_rubber"], run["template"], run["worst"]
    figures: dict[str, Figure] = {}

    def worst(key: str) -> str:
        figures.update({f"{key}_m": exact(w[key]["met"], "d"), f"{key}_n": exact(w[key]["draws"], "d"),
                        f"{key}_k": exact(w[key]["k"], ".2f"), f"{key}_e": exact(w[key]["eta"], ".2f")})
        return f"{{{key}_m}} of {{{key}_n}} draws; worst {{{key}_k}} % / {{{key}_e}} %"

    payne = run["draws"]["payne"]
    figures.update(p_hi=exact(max(d["noise"] for d in payne), ".0f"),
                   p_poor=exact(sum(d["verdict"] == "poor fit" for d in payne), "d"), p_n=exact(len(payne), "d"))
    z = run["draws"]["zerodim6_friction"][0]
    figures.update(z_k=exact(z["k"], ".2f"), z_e=exact(z["eta"], ".2f"), z_x=exact(z["noise"], ".1f"))
    draws = max(x["draws"] for x in w.values())
    return fill(
        f"Measured there (the newest run, {run['date']}, load average {run['load']:g} at its start on 2 cores): on the "
        f"Table-2 campaign of `rapp2022_nr60` ({run['tests']} tests) the identified coupling's bench K' is within "
        "{k} % and its loss factor within {eta} % RMS at validate's " + f"{run['points']}" + " bench points inside the "
        "hull (the paper's map: " + "{pk} % and {pe} %), a " + fr["verdict"] + " ({noise}× the noise), in {wall} s "
        "wall / {cpu} s CPU ({ratio}× the wall time of the preset's own structure, `template`, in the same run; {evals} "
        f"evaluations). On 12-drop campaigns of other structures ({draws} seeded draw{'s' if draws > 1 else ''} each) "
        "K' is within 5 % and the loss factor within 10 % RMS for the Masing banks beside a fractional band ("
        + worst("masing_fractional") + "), the six-parameter forms with a friction bank (" + worst("zerodim6_friction")
        + "), `seed000_six_parameter` (" + worst("seed000_six_parameter") + "), `seed003_masing` ("
        + worst("seed003_masing") + ") and the `payne`-element couplings (" + worst("payne") + "; {p_poor} of {p_n} "
        "judged a poor fit, up to {p_hi}× the noise). The six-parameter forms are met since the stiffening "
        "Maxwell branch: their Maxwell branch stiffens with its deformation (draw #0: loss factor 0.2 to 0.6 with the "
        "amplitude at 30 Hz); before it (the idle run of 2026-11-27) K' 6.8 %, loss factor 24 %, a poor fit (65× the "
        "noise); with it K' {z_k} %, loss factor {z_e} % RMS, a " + z["verdict"] + " ({z_x}× the noise; the branch's "
        "gain fitted, its truth's kind).\n",
        k=exact(fr["k"], ".2f"), eta=exact(fr["eta"], ".2f"), pk=exact(run["paper_k"], ".1f"),
        pe=exact(run["paper_eta"], ".0f"), noise=exact(fr["noise"], ".1f"), wall=timed(fr["wall_s"], ".0f"),
        cpu=on_cpu(fr["cpu_s"], ".0f"), ratio=timed(fr["wall_s"] / tp["wall_s"], ".1f"),
        evals=on_cpu(fr["evaluations"], "d"), **figures)


#: every block: name -> (file relative to the repository, renderer)
BLOCKS: dict[str, tuple[str, Callable[[dict[str, Any]], Block]]] = {
    "map_auto": ("docs/guide/map.md", map_auto),
    "identify_drops": ("docs/guide/identification.md", identify_drops),
    "identify_hard": ("docs/guide/identification.md", identify_hard),
    "bench_table": ("docs/benchmarks.md", bench_table),
    "at_scale": ("docs/benchmarks.md", at_scale),
    "fresh": ("docs/benchmarks.md", fresh_table),
    "campaign_time": ("docs/guide/campaign.md", campaign_time),
    "zerodim20": ("docs/guide/identification.md", zerodim20_times),
    "identify_random_times": ("docs/guide/identification.md", identify_random_times),
    "refit_time": ("docs/routes.md", refit_time),
    "report_size": ("docs/guide/report.md", report_size),
    "study_targets": ("docs/study.md", study_targets),
    "study_results": ("analysis/README.md", study_results),
    "routes": ("docs/routes.md", routes_table),
    "routes_readme": ("README.md", lambda stored: routes_table(stored, outside=False)),
    "uncertainty_coverage": ("docs/guide/uncertainty.md", uncertainty_coverage),
    "core_step": ("docs/benchmarks.md", core_step),
    "report_at_scale": ("docs/campaigns_at_scale.md", report_at_scale),
    "compile_time": ("docs/getting-started.md", compile_time),
    "identify_random": ("docs/guide/identification.md", identify_random_accuracy),
    "map_table4": ("docs/guide/map.md", map_table4),
    "map_nested": ("docs/guide/map.md", map_nested),
    "study_random_angle": ("docs/study.md", study_random_angle),
    "study_case_cv": ("docs/study.md", study_case_cv),
    "uncertainty_cost": ("docs/guide/uncertainty.md", uncertainty_cost),
    "uncertainty_drops": ("docs/guide/uncertainty.md", uncertainty_drops),
    "study_tradeoff": ("docs/study.md", study_tradeoff),
    "first_cycle": ("docs/theory.md", first_cycle_figures),
    "filled_rubber": ("docs/theory.md", filled_rubber),
}


def marked(content: str, name: str) -> tuple[int, int]:
    """Start and end offsets of block ``name``'s content in a page (between its markers)."""
    start, end = START.format(name), END
    first = content.find(start)
    if first < 0 or content.find(start, first + 1) >= 0:
        raise ValueError(f"the page must mark block {name!r} exactly once ({start} ... {end})")
    lo = first + len(start)
    hi = content.find(end, lo)
    if hi < 0:
        raise ValueError(f"block {name!r} has no end marker {end}")
    return lo, hi


def written_block(name: str) -> str:
    path, _ = BLOCKS[name]
    content = (ROOT / path).read_text()
    lo, hi = marked(content, name)
    return content[lo:hi]


def rewrite_readmes(stored: dict[str, Any]) -> list[str]:
    """Rewrite every block from ``stored``; returns the files changed."""
    changed = []
    for path in sorted({p for p, _ in BLOCKS.values()}):
        file = ROOT / path
        content = file.read_text()
        new = content
        for name, (where, render) in BLOCKS.items():
            if where == path:
                lo, hi = marked(new, name)
                new = new[:lo] + "\n\n" + text(render(stored)).strip("\n") + "\n\n" + new[hi:]
        if new != content:
            file.write_text(new)
            changed.append(path)
    return changed


# --- re-running what the figures come from ---------------------------------------------------

def run(command: list[str]) -> None:
    print("$", " ".join(str(c) for c in command), flush=True)
    subprocess.run([str(c) for c in command], cwd=ROOT, check=True)


#: the reduced study's workers when its fingerprint is stored: as tests/test_study.py runs it
FINGERPRINT_WORKERS = 2


def rerun_study() -> None:
    """The full study into a scratch folder, its stored files copied to ``analysis/results/``; and
    the reduced study, whose exact figures are stored beside them as the fingerprint that keys the
    stored study to the code (``analysis/provenance.py``)."""
    sys.path.insert(0, str(ROOT / "analysis"))
    from provenance import FINGERPRINT_FILE, REGENERATE, figures  # analysis/provenance.py

    with tempfile.TemporaryDirectory(prefix="study_") as tmp:
        run([sys.executable, ROOT / "analysis" / "run_study.py", "--out", Path(tmp) / "report"])
        run([sys.executable, ROOT / "analysis" / "run_study.py", "--reduced", "--out", Path(tmp) / "reduced",
             "--workers", str(FINGERPRINT_WORKERS)])
        for name in STUDY_FILES:
            shutil.copy2(Path(tmp) / "report" / name, STUDY_RESULTS / name)
        reduced = json.loads((Path(tmp) / "reduced" / "summary.json").read_text())
        fingerprint = {"what": "the reduced study's figures (run_study.py --reduced): the stored study is current while "
                               "the reduced study reproduces them and its inputs hash the same",
                       "regenerate": REGENERATE, "workers": FINGERPRINT_WORKERS,
                       "inputs_sha256": reduced["provenance"]["inputs_sha256"], "figures": figures(reduced)}
        (STUDY_RESULTS / FINGERPRINT_FILE).write_text(json.dumps(fingerprint, indent=1, allow_nan=True) + "\n")
    print("$", " ".join(NESTED_MAP_COMMAND), ">", NESTED_MAP.relative_to(ROOT), flush=True)
    nested = subprocess.run([sys.executable, *NESTED_MAP_COMMAND], cwd=ROOT, check=True, capture_output=True, text=True)
    NESTED_MAP.write_text(nested.stdout)


def rerun_benchmarks() -> None:
    """Every benchmark, one after the other (they time themselves), each writing its JSON."""
    BENCH_RESULTS.mkdir(parents=True, exist_ok=True)
    for name, script in BENCHMARKS.items():
        run([sys.executable, ROOT / "benchmarks" / script, "--json", BENCH_RESULTS / f"{name}.json"])
    for name, (script, *args) in BENCHMARK_RUNS.items():
        run([sys.executable, ROOT / "benchmarks" / script, *args, "--json", BENCH_RESULTS / f"{name}.json"])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--render-only", action="store_true", help="only rewrite the marked blocks from the stored results")
    ap.add_argument("--skip-study", action="store_true", help="do not re-run the full study")
    ap.add_argument("--skip-benchmarks", action="store_true", help="do not re-run the benchmarks")
    args = ap.parse_args(argv)
    try:
        if not (args.render_only or args.skip_study):
            rerun_study()
        if not (args.render_only or args.skip_benchmarks):
            rerun_benchmarks()
    except subprocess.CalledProcessError as exc:
        print(f"readme_figures: error: {' '.join(str(c) for c in exc.cmd)} failed (exit code {exc.returncode}); "
              "no page was rewritten", file=sys.stderr)
        return 2
    changed = rewrite_readmes(load_stored())
    print(f"figure blocks rewritten from the stored results: {', '.join(changed) or 'none changed'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
