"""False alarms and misses of the drop-test verdict on couplings drawn by a generator of its own.

Other ranges and seeds than the stored hard draws (``random_couplings.hard_truth``,
``bench_identify.py --hard``): slow elastoslides (p = 7 for most draws, v_r 0.03-0.3 rad/s,
where the slip-rate law is stiffest) and zerodim6 couplings whose two Maxwell branches relax
within a factor 1.2-3 of each other (the branches' roles nearly interchangeable), and masing
couplings of broad yield spreads (alpha 2-8, yield limits over a decade and a half: the hard
draws' ranges, other seeds). Each draw: the
12-test virtual campaign of ``bench_identify.py`` (rig ``rapp2022``, sensor noise, three
inertias x four heights), the family's own fit, its servo-grid agreement with the truth, and the
verdict: a false alarm is "poor fit" on a recovered fit (K' <= 1 %, loss factor <= 3 % RMS), a
miss is "good fit" outside 3 % / 10 % (the limits of ``bench_identify.py --hard``). Targets:
false alarms <= 2 % per family over >= 100 draws, misses 0.

Times are CPU seconds (``time.process_time``): the machine these ran on was shared.

    python benchmarks/bench_false_alarms.py --families elastoslide --n 100 --json out.json
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from random_couplings import K_RANGE, _log_uniform, _masing, _within_loss_window  # noqa: E402

#: Families of these draws and the first seed of each (far from the hard draws' 27_000 + ...).
SEEDS = {"elastoslide": 91_000, "zerodim6": 92_000, "masing": 93_000}
#: Recovered / missed limits (K' RMS, loss factor RMS), as ``bench_identify.py --hard``.
RECOVERY_LIMITS = (0.01, 0.03)
MISS_LIMITS = (0.03, 0.10)


def _draw(kind: str, rng) -> dict:
    k = _log_uniform(rng, *K_RANGE)
    if kind == "elastoslide":
        kk = k * rng.uniform(0.6, 1.0)
        p = 7 if rng.uniform() < 0.7 else 5
        return {"name": "alarm_elastoslide", "description": f"p = {p}", "element": [
            {"kind": "elastoslide", "phi0": _log_uniform(rng, 0.005, 0.02), "k": kk, "k0": kk * rng.uniform(0.1, 0.5),
             "v_r": _log_uniform(rng, 0.03, 0.3), "p": p, "n": 32}]}
    if kind == "zerodim6":
        band = (1.0 / (2 * np.pi * 400.0), 3.0 / (2 * np.pi * 15.0))
        t_a = _log_uniform(rng, *band)
        t_b = t_a * _log_uniform(rng, 1.2, 3.0)
        k1 = k * rng.uniform(0.4, 0.8)
        k_a, k_b = (k - k1) * rng.dirichlet([1.0, 1.0])
        gain_on_a = bool(rng.integers(2))
        (kv, tv), (km, tm) = ((k_a, t_a), (k_b, t_b)) if gain_on_a else ((k_b, t_b), (k_a, t_a))
        gain = kv * _log_uniform(rng, 1.0, 300.0)
        return {"name": "alarm_zerodim6", "description": f"tau ratio {t_b / t_a:.2f}, gain on the "
                f"{'faster' if gain_on_a else 'slower'} branch", "element": [
            {"kind": "spring", "stiffness": k1}, {"kind": "maxwell", "stiffness": km, "damping": km * tm},
            {"kind": "variable_maxwell", "stiffness": kv, "stiffness_gain": gain, "damping": kv * tv}]}
    if kind == "masing":
        data = _masing(rng, k, "alarm_masing", (0.001, 0.03), (2.0, 8.0))
        return {**data, "description": f"alpha {data['element'][1]['alpha']:.2f}"}
    raise ValueError(kind)


def alarm_truth(kind: str, rng) -> dict:
    """A coupling of ``kind`` from this benchmark's ranges (the loss-factor window of the other draws kept)."""
    return _within_loss_window(_draw, kind, rng)


def truth_error_over_noise(kind: str, data: dict, decays: list) -> float:
    """The verdict's error over its allowance at the truth itself (the family's vector of the
    drawn coupling, on the same fitting tests): a fit far above it ended off the optimum (the
    search), a truth near the limit means the allowance is too tight (the verdict)."""
    from random_couplings import truth_vector

    from droptower.identify.dropfit import DropFitSettings, DropProblem, drop_scale, drop_verdict, holdout_split
    from droptower.identify.families import family_class

    family = family_class(kind)(drop_scale(decays))
    fit_idx, _ = holdout_split(decays, DropFitSettings().holdout_fraction)
    problem = DropProblem(family, [decays[j] for j in fit_idx], DropFitSettings())
    return float(drop_verdict(problem, truth_vector(kind, data), [], True)[0].error_over_noise)


def run(kind: str, n: int, first: int) -> list[dict]:
    from bench_identify import drawn_campaign

    from droptower.identify.dropfit import identify_drops, servo_agreement

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(first, first + n):
            rng = np.random.default_rng(SEEDS[kind] + i)
            data, truth, decays, excluded, _ = drawn_campaign(lambda r: alarm_truth(kind, r), rng, Path(tmp),
                                                              f"{kind}_{i}")
            c0 = time.process_time()
            result = identify_drops(kind, decays, excluded=excluded)
            cpu = time.process_time() - c0
            agree = servo_agreement(result.coupling, truth, decays)
            k_err, eta_err = agree["storage_stiffness_rms"], agree["loss_factor_rms"]
            recovered = k_err <= RECOVERY_LIMITS[0] and eta_err <= RECOVERY_LIMITS[1]
            good = result.verdict.verdict == "good fit"
            row = {"case": i, "cpu_s": cpu, "k_rms": k_err, "eta_rms": eta_err, "recovered": recovered,
                   "verdict": result.verdict.verdict, "error_over_noise": result.verdict.error_over_noise,
                   "truth_error_over_noise": truth_error_over_noise(kind, data, decays),
                   "false_alarm": recovered and not good,
                   "miss": good and (k_err > MISS_LIMITS[0] or eta_err > MISS_LIMITS[1]),
                   "note": data["description"]}
            rows.append(row)
            print(f"  {kind} #{i}: " + ", ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}"
                                                for k, v in row.items() if k != "case"), flush=True)
    return rows


def summary(kind: str, rows: list[dict]) -> dict:
    cpu = [r["cpu_s"] for r in rows]
    fig = {"draws": len(rows), "false_alarms": int(sum(r["false_alarm"] for r in rows)),
           "false_alarm_pct": 100.0 * float(np.mean([r["false_alarm"] for r in rows])),
           "misses": int(sum(r["miss"] for r in rows)),
           "recovered_pct": 100.0 * float(np.mean([r["recovered"] for r in rows])),
           "worst_k_pct": 100.0 * max(r["k_rms"] for r in rows), "worst_eta_pct": 100.0 * max(r["eta_rms"] for r in rows),
           "median_cpu_s": float(np.median(cpu)), "p90_cpu_s": float(np.percentile(cpu, 90)), "max_cpu_s": float(max(cpu)),
           "rows": rows}
    print(f"## {kind}: {fig['draws']} draws: false alarms {fig['false_alarm_pct']:.1f} % ({fig['false_alarms']}), "
          f"misses {fig['misses']}, recovered {fig['recovered_pct']:.0f} % ({sum(r['recovered'] for r in rows)}/{len(rows)}); "
          f"worst K' {fig['worst_k_pct']:.2f} % / loss factor {fig['worst_eta_pct']:.2f} % RMS; error over allowance "
          f"median {np.median([r['error_over_noise'] for r in rows]):.2f}, max {max(r['error_over_noise'] for r in rows):.2f}; "
          f"CPU per fit median {fig['median_cpu_s']:.1f} s, p90 {fig['p90_cpu_s']:.1f} s, max {fig['max_cpu_s']:.1f} s",
          flush=True)
    return fig


def merge(paths: list[str]) -> dict:
    """The figures of several runs (``--json`` files of disjoint draws, e.g. run side by side),
    their rows joined per family in draw order and summarised again; every row printed."""
    rows: dict[str, list[dict]] = {}
    for path in paths:
        data = json.loads(Path(path).read_text())
        for kind, fig in data.get("figures", data).items():
            rows.setdefault(kind, []).extend(fig["rows"])
    out = {}
    for kind, rs in rows.items():
        rs = sorted(rs, key=lambda r: r["case"])
        out[kind] = summary(kind, rs)
        for r in rs:
            print(f"  {kind} #{r['case']}: " + ", ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}"
                                                       for k, v in r.items() if k != "case"))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--families", default=",".join(SEEDS))
    parser.add_argument("--n", type=int, default=100)
    parser.add_argument("--first", type=int, default=0)
    parser.add_argument("--json", default=None, help="write the figures (with every row) here")
    parser.add_argument("--merge", nargs="+", metavar="JSON", help="join the figures of these runs instead of running")
    args = parser.parse_args()
    if args.merge:
        figures = merge(args.merge)
    else:
        figures = {kind: summary(kind, run(kind, args.n, args.first)) for kind in args.families.split(",")}
    if args.json:
        Path(args.json).write_text(json.dumps({"benchmark": "bench_false_alarms", "machine": {
            "cores": os.cpu_count(), "date": time.strftime("%Y-%m-%d"), "note": "shared; CPU times (time.process_time)"},
            "figures": figures}, indent=1, default=float))


if __name__ == "__main__":
    main()
