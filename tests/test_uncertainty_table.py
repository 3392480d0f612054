"""Per-drop tables with their uncertainties (``*_u``, ``*_U95``, the dominant input) and the
E_n number of ISO 13528 with its verdicts."""
import math

import numpy as np
import pandas as pd
import pytest
import tomli_w
from hypothesis import given, settings
from hypothesis import strategies as st

from droptower.configs import preset_dir, read_toml
from droptower.errors import DroptowerError
from droptower.extract import SyntheticDrop, extract, result_row
from droptower.rig.config import load_rig
from droptower.uncertainty import (VERDICTS, FixtureUncertainty, RigUncertainty, drop_budget, drop_budgets,
                                   en_number, en_verdicts, with_uncertainty)

DEG = math.pi / 180
J = 0.359
GIVEN = RigUncertainty(inertias_kgm2=[FixtureUncertainty(nominal=J, value=0.005)])


def _drops(n=3):
    signals = [SyntheticDrop(duration_s=0.1, seed=i, amplitude_deg=0.5 + i).signals() for i in range(n)]
    return signals, [extract(s) for s in signals]


def test_the_table_gets_u_u95_and_the_dominant_input_in_its_own_units():
    signals, results = _drops()
    table = pd.DataFrame([result_row(f"drop{i}.csv", s, r) for i, (s, r) in enumerate(zip(signals, results))])
    budgets = drop_budgets(results, GIVEN, metadata=[s.metadata for s in signals], method="gum")
    out = with_uncertainty(table, [*budgets[:2], None])
    assert list(out.columns[:len(table.columns)]) == list(table.columns) and len(out) == 3
    for i in range(2):
        c = budgets[i]["stiffness_nm_per_rad"]
        assert out.loc[i, "stiffness_nm_per_deg_u"] == pytest.approx(c.standard_uncertainty * DEG, rel=1e-12)
        assert out.loc[i, "stiffness_nm_per_deg_U95"] == pytest.approx(2 * c.standard_uncertainty * DEG, rel=1e-12)
        assert out.loc[i, "stiffness_nm_per_rad_U95"] == pytest.approx(2 * c.standard_uncertainty, rel=1e-12)
        assert out.loc[i, "stiffness_nm_per_deg_dominant"] == "inertia_kgm2"
        # the stiffness's u holds its fit's *_std and J's share: u² = std² + (c·u_J/J)²
        assert out.loc[i, "stiffness_nm_per_deg_u"] ** 2 == pytest.approx(
            out.loc[i, "stiffness_nm_per_deg_std"] ** 2 + (out.loc[i, "stiffness_nm_per_deg"] * 0.005 / J) ** 2,
            rel=1e-6)
        a = budgets[i]["amplitude_ref_rad"]  # no laser uncertainty given: the fit's alone, and it dominates
        assert out.loc[i, "amplitude_deg_u"] == pytest.approx(out.loc[i, "amplitude_deg_std"], rel=1e-6)
        assert out.loc[i, "amplitude_deg_dominant"] == "fit" and a.method == "GUM"
        assert "laser_radius_m" in out.loc[i, "uncertainty_not_given"].split(";")
    assert np.isnan(out.loc[2, "stiffness_nm_per_deg_u"]) and out.loc[2, "stiffness_nm_per_deg_dominant"] == ""
    for name in ("frequency_hz", "damping_ratio", "loss_factor", "amplitude_deg", "impact_energy_j"):
        assert {f"{name}_u", f"{name}_U95", f"{name}_dominant"} <= set(out.columns), name
    with pytest.raises(DroptowerError, match="2 budgets for 3 rows"):
        with_uncertainty(table, budgets[:2])


def test_a_rig_file_supplies_the_uncertainties_and_the_nominal_values(tmp_path):
    data = read_toml(preset_dir("rigs") / "rapp2022.toml")
    data["uncertainty"] = {"inertias_kgm2": [{"nominal": J, "value": 0.005}],
                           "laser_radius_m": {"value": 0.0015, "distribution": "rectangular"}}
    path = tmp_path / "rig.toml"
    path.write_text(tomli_w.dumps(data))
    rig = load_rig(path)
    signals, results = _drops(1)
    meta = {k: v for k, v in signals[0].metadata.items() if k != "laser_radius_m"}
    b = drop_budget(results[0], rig=rig, metadata=meta, method="gum")
    a = b["amplitude_ref_rad"]  # the rig's radius, 0.15 m, is the nominal one
    assert a.contributions["laser_radius_m"] == pytest.approx(a.value * 0.0015 / math.sqrt(3) / 0.15, rel=1e-6)
    assert b["stiffness_nm_per_rad"].dominant == "inertia_kgm2"


def test_en_numbers_and_verdicts():
    # ISO 13528: E_n = (x_lab - x_ref)/sqrt(U_lab² + U_ref²); |E_n| <= 1 agrees
    out = en_verdicts([100.0, 100.0, 100.0, 100.0], [3.0, 3.0, 3.0, 3.0],
                      [104.0, 106.0, 90.0, 100.0], [4.0, 4.0, np.nan, 4.0])
    assert out["en_number"].iloc[[0, 1, 3]].tolist() == pytest.approx([-0.8, -1.2, 0.0])
    assert out["verdict"].tolist() == ["agrees", "disagrees", VERDICTS[2], "agrees"]
    assert np.isnan(out["en_number"].iloc[2])
    assert en_verdicts([1.0, 2.0], [0.1, 0.1], [1.0, 2.0])["verdict"].tolist() == [VERDICTS[2]] * 2
    # one relative figure for the bench where it gives none per point
    rel = en_verdicts([100.0, 100.0], [3.0, 3.0], [104.0, 90.0], [np.nan, 1.0], u95_ref_rel=0.04)
    assert rel["en_number"].tolist() == pytest.approx([-4 / math.hypot(3, 4.16), 10 / math.hypot(3, 1)])
    assert float(en_number(1.0, 0.0, 2.0, 0.5)) == -2.0
    for args, kwargs, where in [(([1.0], [0.1], [1.0]), {"u95_ref": [-1.0]}, "u95_ref"),
                                (([1.0], [0.1], [1.0]), {"u95_ref_rel": -0.1}, "u95_ref_rel"),
                                (([1.0], [0.0], [1.0]), {"u95_ref_rel": 0.0}, "both 0"),
                                (([np.nan], [0.1], [1.0]), {}, "x_lab: sample 0 is NaN"),
                                (([1.0, 2.0], [0.1], [1.0, 2.0, 3.0]), {}, "do not match")]:
        with pytest.raises(DroptowerError, match=where):
            en_verdicts(*args, **kwargs)


@settings(max_examples=100, derandomize=True, deadline=None)
@given(x=st.floats(-1e6, 1e6), y=st.floats(-1e6, 1e6), u1=st.floats(1e-6, 1e5), u2=st.floats(1e-6, 1e5))
def test_en_is_antisymmetric_and_agrees_exactly_within_the_combined_interval(x, y, u1, u2):
    en = float(en_number(x, u1, y, u2))
    assert float(en_number(y, u2, x, u1)) == -en
    verdict = en_verdicts([x], [u1], [y], [u2])["verdict"].iloc[0]
    assert (verdict == "agrees") == (abs(x - y) / math.hypot(u1, u2) <= 1.0)


def test_route_agreement_judges_each_point_and_names_a_missing_bench_uncertainty():
    from droptower.uncertainty import format_agreement, route_agreement

    table = pd.DataFrame({"sweep": ["f"] * 3, "amplitude_deg": [0.5, 1.0, 1.5], "frequency_hz": [10.0, 20.0, 30.0],
                          "in_range": [True, True, False], "map_stiffness_nm_per_deg": [100.0, 103.0, 110.0],
                          "servo_stiffness_nm_per_deg": [100.0, 100.0, 100.0],
                          "map_damping_ratio": [1.0, 1.0, 1.0], "servo_damping_ratio": [1.0, 1.0, 1.0]})
    out = route_agreement(table, {"stiffness_nm_per_deg": [4.0, 4.0, 4.0]}, u95_ref_rel=0.03)
    # E_n = (x1 - x2)/sqrt(U1² + U2²): 3/sqrt(16 + 9) = 0.6; 10/5 = 2
    np.testing.assert_allclose(out["stiffness_nm_per_deg_en_number"], [0.0, 0.6, 2.0])
    assert list(out["stiffness_nm_per_deg_verdict"]) == ["agrees", "agrees", "disagrees"]
    assert "damping_ratio_verdict" not in out  # no U95 of the route's damping: not judged
    none = route_agreement(table, {"stiffness_nm_per_deg": 4.0})
    assert set(none["stiffness_nm_per_deg_verdict"]) == {"bench uncertainty not given"}
    text = format_agreement({"r": out, "s": none})
    assert "inside: 2/2 agree" in text and "all: 2/3 agree, max |E_n| 2.00" in text
    assert "s, stiffness_nm_per_deg: inside: bench uncertainty not given" in text


def test_a_servo_tables_own_u95_column_is_read_by_point(tmp_path):
    from droptower.compare import read_servo_results
    from droptower.compare.validate import servo_u95_columns

    path = tmp_path / "servo.csv"
    path.write_text("amplitude_deg,frequency_hz,storage_stiffness_nm_per_deg,loss_factor,storage_stiffness_nm_per_deg_U95\n"
                    "0.5,10,300,0.2,6\n0.5,20,310,0.21,6.2\n1.5,10,280,0.25,5.6\n")
    points = read_servo_results(path)  # its table is sorted: the U95 follows its point, not its row
    u95 = servo_u95_columns(points, points.table)
    lookup = {(0.5, 10.0): 6.0, (0.5, 20.0): 6.2, (1.5, 10.0): 5.6}
    expected = [lookup[(a, f)] for a, f in zip(points.table["amplitude_deg"], points.table["frequency_hz"])]
    np.testing.assert_allclose(u95["stiffness_nm_per_deg"], expected)
    assert "damping_ratio" not in u95


def test_a_campaigns_budgets_reuse_monte_carlo_where_the_make_up_is_the_same():
    """campaign_budgets against both methods on every drop: U95 and the interval's ends within
    5 % of U95 (the GUM-vs-Monte-Carlo criterion), with Monte Carlo on a few drops only; the
    amplitude, dominated by a rectangular calibration, stays Monte Carlo's (GUM 4.3.7: ±1.65 u)."""
    from droptower.rig.uncertainty import override_uncertainty
    from droptower.uncertainty import campaign_budgets

    signals = [SyntheticDrop(duration_s=0.1, seed=i, amplitude_deg=1.0 + 0.02 * (i % 3)).signals() for i in range(9)]
    results = [extract(s) for s in signals]
    u = override_uncertainty(None, [f"inertia_kgm2@{J}={0.01 * J}", "laser_calibration_rel=0.003:rectangular",
                                    "sample_rate_hz=0.3"])
    metas = [s.metadata for s in signals]
    fast = campaign_budgets(results, u, metadata=metas)
    full = drop_budgets(results, u, metadata=metas, method="auto")
    assert sum(b.trials > 0 for b in fast) < len(fast) / 2
    for b, f in zip(fast, full):
        for name, q in f.quantities.items():
            if q.expanded_uncertainty > 0:
                tol = 0.05 * q.expanded_uncertainty
                assert abs(b[name].expanded_uncertainty - q.expanded_uncertainty) <= tol, name
                # the ends: a GUM interval is y ± 2u by convention (k = 2), Monte Carlo's its 95 % quantiles
                # (±1.96u for a normal output): a borderline validation may pick either
                ends = tol + (2 - 1.96) * q.standard_uncertainty
                assert abs(b[name].low - q.low) <= ends and abs(b[name].high - q.high) <= ends, name
        assert f["amplitude_ref_rad"].method == "MC"
