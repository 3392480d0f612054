"""Benchmark: ``droptower extract`` throughput on 10 000-sample CSV logs, parsing included.

Target: >= 100 logs/s on this machine. Prints logs/s, the share of time spent
parsing (read_any + map_channels) and fitting (extract), and the ratio to a naive baseline
measured in the same run: ``pandas.read_csv`` + ``scipy.optimize.curve_fit`` of the same
decay model over the first cycle (impact from the force peak, no uncertainties, no flags).

    python benchmarks/bench_extract.py [--logs 200]
"""
from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from droptower.extract.extractor import extract
from droptower.extract.files import Settings
from droptower.extract.synthetic import SyntheticDrop
from droptower.io.mapping import map_channels
from droptower.io.readers import read_any
from droptower.rates import RIG_SAMPLE_RATE_HZ
from timing import json_option, write_figures

SAMPLES = 10_000
RATE = RIG_SAMPLE_RATE_HZ


def make_logs(folder: Path, count: int) -> list[Path]:
    rng = np.random.default_rng(0)
    paths = []
    for i in range(count):
        drop = SyntheticDrop(stiffness_nm_per_rad=rng.uniform(9e3, 2.2e4), damping_ratio=rng.uniform(1.0, 1.8),
                             amplitude_deg=rng.uniform(0.2, 3.0), ringing_fraction=0.3, duration_s=SAMPLES / RATE,
                             sample_rate_hz=RATE, seed=i)
        paths.append(drop.write(folder / f"drop_{i:04d}.csv"))
    return paths


def run_droptower(paths: list[Path], clock=time.perf_counter) -> tuple[float, float, list[float]]:
    settings = Settings()
    parse = fit = 0.0
    stiffness = []
    for path in paths:
        t0 = clock()
        signals = map_channels(read_any(path), settings.roles, sensor_radius_m=None)
        t1 = clock()
        result = extract(signals, window=settings.window)
        t2 = clock()
        parse, fit = parse + (t1 - t0), fit + (t2 - t1)
        stiffness.append(result.stiffness_nm_per_rad)
    return parse, fit, stiffness


def run_naive(paths: list[Path], clock=time.perf_counter) -> tuple[float, list[float]]:
    """The obvious script: pandas + curve_fit, starting values from an FFT of the record."""
    import pandas as pd
    from scipy.optimize import curve_fit

    def model(t, amp, delta, omega, phase):
        return amp * np.exp(-delta * t) * np.cos(omega * t - phase)

    t0 = clock()
    stiffness = []
    for path in paths:
        frame = pd.read_csv(path, comment="#")
        t, angle, force = frame["time_s"].to_numpy(), frame["angle_rad"].to_numpy(), frame["impact_force_n"].to_numpy()
        onset = int(np.argmax(force))
        y = angle[onset:] - angle[: onset - 5].mean()
        tt = t[onset:] - t[onset]
        spectrum = np.abs(np.fft.rfft(y, 16 * y.size))
        omega0 = 2 * np.pi * np.fft.rfftfreq(16 * y.size, tt[1] - tt[0])[np.argmax(spectrum)]
        cycle = tt <= 2 * np.pi / omega0
        popt, _ = curve_fit(model, tt[cycle], y[cycle], p0=[np.abs(y).max(), 0.1 * omega0, omega0, np.pi / 2])
        stiffness.append(float(np.mean(frame.attrs.get("J", 0.359)) * (popt[2] ** 2 + popt[1] ** 2)))
    return clock() - t0, stiffness


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--logs", type=int, default=200)
    json_option(parser)
    args = parser.parse_args()
    figures = {"logs": args.logs}
    with tempfile.TemporaryDirectory() as tmp:
        paths = make_logs(Path(tmp), args.logs)
        run_droptower(paths[:5])  # warm-up: imports, caches
        run_naive(paths[:5])
        print(f"logs: {len(paths)} CSV files x {SAMPLES} samples x 4 columns (droptower-log CSV, {RATE / 1e3:g} kHz), "
              f"one process; load average before: {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
        for label, clock in (("wall time", time.perf_counter), ("CPU time, all threads", time.process_time)):
            parse, fit, ours = run_droptower(paths, clock)
            naive_s, theirs = run_naive(paths, clock)
            total = parse + fit
            rate, naive_rate = len(paths) / total, len(paths) / naive_s
            print(f"[{label}]")
            print(f"  droptower (read_any + map_channels + extract): {rate:7.1f} logs/s  (target >= 100)")
            print(f"    parsing {100 * parse / total:5.1f} %  ({1e3 * parse / len(paths):.2f} ms/log)")
            print(f"    fitting {100 * fit / total:5.1f} %  ({1e3 * fit / len(paths):.2f} ms/log)")
            print(f"  naive baseline (pandas.read_csv + scipy curve_fit): {naive_rate:7.1f} logs/s")
            print(f"  ratio droptower / naive: {rate / naive_rate:.2f}x")
            key = "wall" if clock is time.perf_counter else "cpu"
            figures.update({f"{key}_logs_per_s": rate, f"{key}_parsing_share_pct": 100 * parse / total,
                            f"{key}_naive_logs_per_s": naive_rate})
    spread = np.median(np.abs(np.array(ours) / np.array(theirs) - 1))
    print(f"median |c_droptower / c_naive - 1| = {spread:.2e} (same model, both converge)")
    write_figures(args.json, "bench_extract", figures)


if __name__ == "__main__":
    main()
