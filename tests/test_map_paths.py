"""The map drawn over the tests follows each lever's realised (amplitude, frequency) path, so
at every test the curve is the map's value at that test's own amplitude and frequency."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from droptower.maps import fit_map, read_results, select_tests
from droptower.maps.plots import _frequency_along, path_grid, plot_damping_map
from pictures import assert_drawn


@pytest.fixture(scope="module")
def table4():
    tests = select_tests(read_results("rapp2022_table4"), "rapp2022_table4")[0]
    return tests, fit_map(tests, source="rapp2022_table4")


def test_the_path_passes_through_every_test():
    rng = np.random.default_rng(2)
    rows = pd.DataFrame({"amplitude_deg": rng.uniform(0.1, 2.0, 9), "frequency_hz": rng.uniform(30.0, 60.0, 9)})
    a = rows["amplitude_deg"].to_numpy()
    np.testing.assert_allclose(_frequency_along(rows, a), rows["frequency_hz"], rtol=1e-12)
    grid = path_grid(a)
    assert np.isin(a, grid).all() and np.all(np.diff(grid) > 0)
    # repeats at one amplitude: their geometric mean frequency
    twice = pd.DataFrame({"amplitude_deg": [0.5, 0.5, 1.0], "frequency_hz": [40.0, 50.0, 30.0]})
    assert _frequency_along(twice, np.array([0.5]))[0] == pytest.approx(np.sqrt(40.0 * 50.0))


def test_report_damping_curve_per_inertia_is_the_map_at_each_test(table4):
    from droptower.report.figures import map_figure

    tests, fit = table4
    fig = map_figure(tests, [f"t{i}" for i in range(len(tests))], fit)
    lines = [t for t in fig.data if t.mode == "lines" and t.xaxis == "x2"]
    groups = tests.groupby(tests["inertia_kgm2"].astype(float).round(6))
    assert len(lines) == groups.ngroups == 3
    for line, (_, rows) in zip(lines, groups):
        x, y = np.asarray(line.x), np.asarray(line.y)
        for a, f in zip(rows["amplitude_deg"], rows["frequency_hz"]):
            assert y[np.flatnonzero(x == a)[0]] == pytest.approx(float(fit.damping_ratio(a, f)), rel=1e-12)


def test_map_plot_draws_one_damping_curve_per_inertia(table4, tmp_path):
    tests, fit = table4
    plot_damping_map(tests, fit, tmp_path / "fig13.png")
    assert_drawn(tmp_path / "fig13.png")
