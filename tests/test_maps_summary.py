"""Per-condition summary (mean ± std over repeats) and Rapp et al. 2022, Fig. 11 (the preload's effect)."""
from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

from droptower.maps.summary import condition_summary, plot_preload_effect, preload_effect_pct
from pictures import assert_drawn


def results() -> pd.DataFrame:
    """Two heights x two preloads x three repeats; the 500 N*m tests 2 % stiffer; one flagged test."""
    rows = []
    for height, amplitude in ((0.2, 0.5), (1.0, 1.5)):
        for preload in (0.0, 500.0):
            for repeat, dev in enumerate((-1.0, 0.0, 1.0)):
                rows.append({"case": "case 2", "inertia_kgm2": 0.359, "drop_mass_kg": 2.0, "drop_height_m": height,
                             "preload_nm": preload, "repeat": repeat, "amplitude_deg": amplitude + 0.01 * dev,
                             "frequency_hz": 30.0 + dev, "damping_ratio": 1.2 + 0.1 * dev, "flags": "",
                             "stiffness_nm_per_deg": (200.0 + 4.0 * dev) * (1.02 if preload else 1.0)})
    table = pd.DataFrame(rows)
    flagged = table.iloc[[0]].assign(stiffness_nm_per_deg=1e6, flags="double_impact")
    return pd.concat([table, flagged], ignore_index=True)


def test_mean_and_std_over_repeats_without_flagged_tests() -> None:
    summary = condition_summary(results())
    assert len(summary) == 4 and (summary["n_tests"] == 3).all()  # the flagged repeat is left out
    first = summary.iloc[0]
    assert first["stiffness_nm_per_deg_mean"] == pytest.approx(200.0)
    assert first["stiffness_nm_per_deg_std_over_repeats"] == pytest.approx(4.0)  # ddof = 1 of (-4, 0, 4)
    assert first["frequency_hz_std_over_repeats"] == pytest.approx(1.0)
    assert summary.loc[1, "stiffness_nm_per_deg_mean"] == pytest.approx(204.0)  # preload 500 N*m
    assert preload_effect_pct(summary, "stiffness_nm_per_deg") == pytest.approx(2.0)
    assert preload_effect_pct(summary, "damping_ratio") == pytest.approx(0.0, abs=1e-12)


def test_single_repeat_has_no_std_and_fig11_is_drawn(tmp_path: Path) -> None:
    table = results()
    summary = condition_summary(table[table["repeat"] == 1])
    assert (summary["n_tests"] == 1).all() and summary["stiffness_nm_per_deg_std_over_repeats"].isna().all()
    path = plot_preload_effect(condition_summary(table), tmp_path / "fig11.png", "test plan")
    assert_drawn(path, panels=2)  # stiffness and damping ratio
