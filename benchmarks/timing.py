"""Shared by the benchmark scripts (run as ``python benchmarks/bench_x.py``, which puts this
folder on the import path)."""
from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import time
from pathlib import Path
from typing import Callable


def best_of(fn: Callable[[], object], repeat: int, clock: Callable[[], float] = time.perf_counter) -> float:
    """The shortest time (s) of ``repeat`` calls on ``clock`` (wall time by default; ``time.process_time``
    for this process's CPU time, which other jobs on the machine do not stretch)."""
    times = []
    for _ in range(repeat):
        t0 = clock()
        fn()
        times.append(clock() - t0)
    return min(times)


LOAD_AT_START = os.getloadavg()[0]  # when the benchmark started (imported this module)


def machine() -> dict[str, object]:
    """The machine a figure was measured on: cores, processor, Python, load average (start and end)."""
    model = platform.processor() or platform.machine()
    cpuinfo = Path("/proc/cpuinfo")
    if cpuinfo.is_file():
        names = [line.split(":", 1)[1].strip() for line in cpuinfo.read_text().splitlines() if line.startswith("model name")]
        model = names[0] if names else model
    return {"cores": os.cpu_count(), "processor": model, "python": platform.python_version(),
            "load_average_start": round(LOAD_AT_START, 2), "load_average_end": round(os.getloadavg()[0], 2),
            "date": datetime.date.today().isoformat()}


def write_figures(path: Path | None, benchmark: str, figures: dict[str, object]) -> None:
    """``--json PATH``: the printed figures (units in their names) and the machine, as one JSON file
    (``analysis/readme_figures.py`` renders the README's tables from it)."""
    if path is None:
        return
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps({"benchmark": benchmark, "machine": machine(), "figures": figures}, indent=1) + "\n")
    print(f"figures written to {path}")


def json_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--json", type=Path, default=None, metavar="PATH",
                        help="also write the figures to this JSON file (e.g. benchmarks/results/NAME.json)")
