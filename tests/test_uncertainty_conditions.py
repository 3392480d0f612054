"""Each condition's budget (droptower.uncertainty.conditions): the repeats' share shrinks as
1/√n, the inputs' does not, and the largest term is the one built to dominate."""
from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings, strategies as st

from droptower.report.page import budget_section
from droptower.rig.uncertainty import override_uncertainty
from droptower.uncertainty import condition_budgets

J, FS, R = 0.359, 2048.0, 0.15


def _table(n: int, spread: float = 0.01, seed: int = 0) -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    c = 250.0 * (1 + spread * rng.standard_normal(n))
    return pd.DataFrame({"inertia_kgm2": J, "drop_height_m": 0.5, "sample_rate_hz": FS, "sensor_radius_m": R,
                         "stiffness_nm_per_deg": c, "stiffness_nm_per_deg_std": 0.5,
                         "damping_ratio": 1.0 + 0.01 * rng.standard_normal(n), "damping_ratio_std": 0.01,
                         "amplitude_deg": 1.0 + 0.001 * rng.standard_normal(n), "amplitude_deg_std": 0.001,
                         "frequency_hz": 30.0 + 0.01 * rng.standard_normal(n), "frequency_hz_std": 0.01})


def test_the_closed_forms_of_one_conditions_budget():
    table = _table(9)
    u = override_uncertainty(None, [f"inertia_kgm2@{J}=0.0036", "sample_rate_hz=0.2", "laser_radius_m=0.0003"])
    b = condition_budgets(table, u).set_index("quantity")
    c = table["stiffness_nm_per_deg"]
    s = b.loc["stiffness_nm_per_deg"]
    assert s["u_repeats"] == pytest.approx(c.std(ddof=1) / 3)           # s/√n, n = 9
    assert s["u_inertia_kgm2"] == pytest.approx(c.mean() * 0.0036 / J)  # c ∝ J
    assert s["u_sample_rate_hz"] == pytest.approx(c.mean() * 2 * 0.2 / FS)  # c ∝ f_s²
    assert s["U95"] == pytest.approx(2 * math.sqrt(s["u_repeats"] ** 2 + s["u_inertia_kgm2"] ** 2
                                                   + s["u_sample_rate_hz"] ** 2))
    assert s["dominant"] == "inertia_kgm2"
    assert b.loc["amplitude_deg", "u_laser_radius_m"] == pytest.approx(table["amplitude_deg"].mean() * 0.0003 / R)
    assert math.isnan(b.loc["damping_ratio", "u_inertia_kgm2"])  # d carries no J
    heading, body = budget_section(table, u)
    assert heading == "Uncertainty budget per condition" and "inertia_kgm2, laser_radius_m, sample_rate_hz" in body


def test_the_repeats_share_shrinks_and_the_inertias_stays():
    u = override_uncertainty(None, [f"inertia_kgm2@{J}=0.0036"])
    few, many = (condition_budgets(_table(n, seed=1), u).set_index("quantity").loc["stiffness_nm_per_deg"]
                 for n in (4, 64))
    assert many["u_repeats"] < few["u_repeats"] / 2.5  # ~1/√16 = 1/4, scatter of s aside
    assert many["u_inertia_kgm2"] == pytest.approx(few["u_inertia_kgm2"], rel=0.01)
    assert few["dominant"] == "repeats" or many["dominant"] == "inertia_kgm2"


@settings(derandomize=True, max_examples=25, deadline=None)
@given(st.sampled_from(["repeats", "inertia_kgm2", "sample_rate_hz"]), st.floats(3.0, 30.0))
def test_the_largest_term_is_the_one_built_to_dominate(which, factor):
    """One source made `factor` times the others' size (relative 0.1 % each otherwise)."""
    base = 0.001
    spread = base * (factor if which == "repeats" else 1.0) * 3  # s/√9 = spread·c
    u_j = base * (factor if which == "inertia_kgm2" else 1.0) * J
    u_fs = base * (factor if which == "sample_rate_hz" else 1.0) * FS / 2
    table = _table(9, spread=0.0)
    rng = np.random.default_rng(0)
    noise = rng.standard_normal(9)
    noise = (noise - noise.mean()) / noise.std(ddof=1)  # exactly unit sample deviation
    table["stiffness_nm_per_deg"] = 250.0 * (1 + spread * noise)
    u = override_uncertainty(None, [f"inertia_kgm2@{J}={u_j!r}", f"sample_rate_hz={u_fs!r}"])
    row = condition_budgets(table, u).set_index("quantity").loc["stiffness_nm_per_deg"]
    assert row["dominant"] == which
    assert row["dominant_share_pct"] == pytest.approx(100 * factor ** 2 / (factor ** 2 + 2), rel=1e-6)
