"""One servo grid inside the tested range (droptower.identify.dropfit.SERVO_GRID): the acceptance
measure, the drop-test report's servo prediction and the documentation all use it."""
from __future__ import annotations

import re
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from droptower.identify import dropfit
from droptower.identify.dropfit import SERVO_GRID

REPO = Path(__file__).resolve().parents[1]
#: "servo grid 4 amplitudes × 3 frequencies", "a 4 x 3 servo grid"
STATED = re.compile(r"servo grid (\d+) amplitudes [×x] (\d+) frequencies|(\d+) [×x] (\d+) servo grid")


def _stated(text: str) -> list[tuple[int, int]]:
    return [tuple(int(g) for g in m.groups() if g is not None) for m in STATED.finditer(text)]


def test_the_grid_spans_the_tested_range_geometrically():
    rng = np.random.default_rng(29)
    decays = [SimpleNamespace(amplitude_rad=a, frequency_hz=f)
              for a, f in zip(rng.uniform(0.002, 0.05, 7), rng.uniform(5.0, 60.0, 7))]
    amplitudes, frequencies = dropfit.tested_grid(decays)
    assert (amplitudes.size, frequencies.size) == SERVO_GRID
    a = [d.amplitude_rad for d in decays]
    f = [d.frequency_hz for d in decays]
    for values, lo, hi in ((amplitudes, min(a), max(a)), (frequencies, min(f), max(f))):
        assert np.isclose(values[0], lo, rtol=1e-12) and np.isclose(values[-1], hi, rtol=1e-12)
        ratios = values[1:] / values[:-1]
        assert np.allclose(ratios, (hi / lo) ** (1.0 / (values.size - 1)), rtol=1e-12)  # geometric


def test_the_documentation_states_the_one_grid():
    assert _stated("servo grid 4 amplitudes × 3 frequencies; the 5 x 4 servo grid") == [(4, 3), (5, 4)]
    sources = [REPO / "README.md", *sorted((REPO / "docs").rglob("*.md")),
               REPO / "benchmarks" / "bench_identify.py", REPO / "analysis" / "readme_figures.py"]
    stated = {(path.relative_to(REPO).as_posix(), grid) for path in sources
              for grid in _stated(path.read_text(encoding="utf-8"))}
    assert stated, "no page states the servo grid any more: drop this test or the constant's docs"
    assert all(grid == SERVO_GRID for _, grid in stated), sorted(stated)
