"""Shared by the benchmark scripts (run as ``python benchmarks/bench_x.py``, which puts this
folder on the import path)."""
from __future__ import annotations

import time
from typing import Callable


def best_of(fn: Callable[[], object], repeat: int) -> float:
    """The shortest wall time (s) of ``repeat`` calls: the figure least disturbed by other load."""
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)
