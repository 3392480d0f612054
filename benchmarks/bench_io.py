"""Parse throughput of 10 000-sample drop-test logs (target: >= 100 logs/s for parse + fit).

Times reading + channel mapping per format and compares with a naive baseline measured in the
same run: ``numpy.loadtxt`` of the same CSV body. Run: ``python benchmarks/bench_io.py``.
"""
from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from droptower.io import map_channels, read_any, write_log
from droptower.rates import RIG_SAMPLE_RATE_HZ

N_SAMPLES = 10_000
REPEAT = 40


def _logs(folder: Path) -> dict[str, Path]:
    rng = np.random.default_rng(1)
    t = np.arange(N_SAMPLES) / RIG_SAMPLE_RATE_HZ
    angle = 0.02 * np.exp(-40 * t) * np.sin(2 * np.pi * 60 * t) + 1e-5 * rng.normal(size=t.size)
    channels = {"angle_rad": angle, "torque_nm": 900 * angle + rng.normal(size=t.size),
                "impact_force_n": 1e3 * np.exp(-((t - 0.01) / 1e-3) ** 2), "laser_distance_m": 0.1 * angle}
    paths = {"droptower csv": write_log(folder / "own.csv", t, channels, {"inertia_kgm2": 0.01}),
             "droptower parquet": write_log(folder / "own.parquet", t, channels, {"inertia_kgm2": 0.01})}
    table = np.column_stack([t, *channels.values()])
    lab = folder / "lab.csv"  # German lab export: semicolon, decimal comma, unit row, header lines
    body = "\n".join(";".join(repr(v).replace(".", ",") for v in row) for row in table.tolist())
    lab.write_text("Versuch 7\nPruefer: X\nZeit;Winkel;Moment;Kraft;Laser\ns;rad;N*m;N;m\n" + body + "\n", encoding="utf-8")
    paths["lab csv (; and ,)"] = lab
    plain = folder / "plain.csv"
    plain.write_text("time [s],angle [rad],torque [N*m],force [N],laser [m]\n"
                     + "\n".join(",".join(map(repr, row)) for row in table.tolist()) + "\n")
    paths["plain csv"] = plain
    return paths


def _rate(fn, repeat: int = REPEAT) -> float:
    fn()  # warm-up: imports, caches
    start = time.perf_counter()
    for _ in range(repeat):
        fn()
    return repeat / (time.perf_counter() - start)


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        paths = _logs(Path(tmp))
        baseline = _rate(lambda: np.loadtxt(paths["plain csv"], delimiter=",", skiprows=1), 10)
        print(f"{N_SAMPLES} samples x 5 channels per log; baseline numpy.loadtxt: {baseline:8.1f} logs/s")
        print(f"{'format':22s} {'read logs/s':>12s} {'read+map logs/s':>16s} {'vs baseline':>12s}")
        for name, path in paths.items():
            read = _rate(lambda: read_any(path))
            full = _rate(lambda: map_channels(read_any(path), sensor_radius_m=0.1))
            print(f"{name:22s} {read:12.1f} {full:16.1f} {full / baseline:11.1f}x")


if __name__ == "__main__":
    main()
