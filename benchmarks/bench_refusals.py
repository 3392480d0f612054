"""How fast a request beyond the limits is refused (the checks ``tests/test_hardening.py`` makes
by memory, here by time): each refusal against a baseline measured in the same run, the
smallest served request of the same command (one servo point of 2 cycles at 10 Hz). A refusal
is sized before anything is allocated, so it must cost no more than that baseline; the script
prints the ratio. Run: ``python benchmarks/bench_refusals.py``.
"""
from __future__ import annotations

import contextlib
import io
import tempfile
import time
from pathlib import Path

from droptower.cli.main import main

HUGE = '[[element]]\nkind = "elastoslide"\nn = 1000000000\nk = 1.0\nk0 = 1.0\nv_r = 1.0\nphi0 = 1.0\n'
BASE = ["servo", "rapp2022_nr60", "--amplitude-deg", "1", "--frequency-hz", "10", "--cycles", "2", "-q"]


def _best(argv: list[str], expected: int, repeat: int = 5) -> float:
    """Best-of-``repeat`` wall time (s) of ``droptower ARGV``, checking its exit code."""
    best = float("inf")
    for _ in range(repeat):
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            start = time.perf_counter()
            code = main(argv)
            best = min(best, time.perf_counter() - start)
        assert code == expected, (argv, code)
    return best


def main_() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        huge = Path(tmp) / "huge.toml"
        huge.write_text(HUGE)
        cases = {
            "coupling of n = 1e9 elements": (["servo", str(huge), "--amplitude-deg", "1", "--frequency-hz", "10"], 2),
            "servo run at 1e-6 Hz": (["servo", "rapp2022_nr60", "--amplitude-deg", "1", "--frequency-hz", "1e-6"], 2),
            "servo run of 1e9 cycles": (["servo", "rapp2022_nr60", "--amplitude-deg", "1", "--frequency-hz", "10",
                                         "--cycles", "1000000000"], 2),
            "simulate 1e9 s after the impact": (["simulate", "--inertia-kgm2", "0.359", "--drop-mass-kg", "2",
                                                 "--height-m", "1", "--duration-s", "1e9"], 2),
        }
        _best(BASE, 0, 1)  # warm-up: imports and compiled kernels
        baseline = _best(BASE, 0)
        print(f"baseline, the smallest served servo request (1 point, 2 cycles at 10 Hz): {1e3 * baseline:8.1f} ms")
        print(f"{'refused request':34s} {'time ms':>9s} {'vs baseline':>12s}")
        for name, (argv, code) in cases.items():
            t = _best(argv, code)
            print(f"{name:34s} {1e3 * t:9.1f} {t / baseline:11.3f}x")


if __name__ == "__main__":
    main_()
