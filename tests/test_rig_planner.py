"""The campaign planner: nonlinear free decay, double-impact check, warnings."""
import math

import numpy as np
import pandas as pd
import pytest
import tomli_w

from droptower.configs import preset_dir, read_toml
from droptower.rheology import load_coupling
from droptower.rheology.loader import parse_coupling
from droptower.rig.config import load_doe, load_rig
from droptower.rig.impact_law import impact_velocities, linear_free_decay
from droptower.rig.predictions import plan

K, D = 14000.0, 15.55


@pytest.fixture(scope="module")
def rig():
    return load_rig("rapp2022")


def linear(k=K, d=D):
    return parse_coupling({"element": [{"kind": "spring", "stiffness": k}, {"kind": "dashpot", "damping": d}]})


def conditions(rows):
    return pd.DataFrame(rows, columns=["inertia_kgm2", "drop_mass_kg", "drop_height_m", "preload_nm"])


def test_linear_coupling_matches_the_closed_form(rig):
    rows = [(J, m, h, p) for J, m in ((0.1557, 1.0), (0.5233, 2.0)) for h in (0.05, 6.0) for p in (0.0, 1000.0)]
    table = plan(rig, linear(), conditions(rows))
    for row in table.itertuples():
        iv = impact_velocities(row.drop_mass_kg, row.inertia_kgm2, 0.2, row.drop_height_m, 0.5)
        assert row.lever_rate_after_rad_per_s == pytest.approx(float(iv.rate_after_rad_per_s), rel=1e-12)
        t = np.linspace(0, 0.06, 600001)
        phi, delta, omega = linear_free_decay(K, D, row.inertia_kgm2, iv.rate_after_rad_per_s, t)
        assert row.first_period_s == pytest.approx(2 * math.pi / omega, rel=1e-3)
        assert row.first_peak_deg == pytest.approx(math.degrees(phi.max()), rel=1e-3)
        assert row.decay_coefficient_per_s == pytest.approx(delta, rel=5e-3)
        assert row.damping_ratio == pytest.approx(0.5 * math.expm1(4 * math.pi * delta / omega), rel=5e-3)
        torque = K * phi + D * np.gradient(phi, t)
        assert row.peak_torque_nm == pytest.approx(row.preload_nm + torque[t <= row.first_period_s].max(), rel=2e-3)
        assert row.pretwist_deg == pytest.approx(math.degrees(row.preload_nm / K), rel=1e-6)
        # eq. 18 on the first cycle: the envelope at half a period
        assert row.amplitude_deg == pytest.approx(
            math.degrees(iv.rate_after_rad_per_s / omega * math.exp(-delta * math.pi / omega)), rel=5e-3)


def test_conditions_planned_together_equal_planned_alone(rig):
    coupling = load_coupling("rapp2022_nr60")
    rows = [(0.1557, 1.0, 0.2, 0.0), (0.359, 2.0, 1.4, 500.0), (0.5233, 2.0, 6.0, 1000.0)]
    together = plan(rig, coupling, conditions(rows))
    for i, r in enumerate(rows):
        alone = plan(rig, coupling, conditions([r]))
        for col in ("amplitude_deg", "first_period_frequency_hz", "peak_torque_nm", "min_clearance_mm"):
            assert together[col][i] == pytest.approx(alone[col][0], rel=1e-9)


def test_table2_with_the_reference_coupling(rig):
    """Every Table 2 condition on the nonlinear coupling: no double impact, within the rig's limits."""
    doe = load_doe("rapp2022_table2")
    table = plan(rig, load_coupling("rapp2022_nr60"), doe.conditions())
    assert len(table) == 90 and (table["repeats"] == 5).all()
    assert not table["double_impact"].any()
    assert (table["warnings"].map(len) == 0).all()
    # amplitude grows with the drop height, frequency falls with it (softening coupling, Table 4)
    for _, grp in table[table["preload_nm"] == 0].groupby("case"):
        assert grp["amplitude_deg"].is_monotonic_increasing
        assert grp["first_period_frequency_hz"].is_monotonic_decreasing


def _rig(tmp_path, **changes):
    data = read_toml(preset_dir("rigs") / "rapp2022.toml")
    for dotted, value in changes.items():
        node = data
        *parents, leaf = dotted.split(".")
        for p in parents:
            node = node[p]
        node[leaf] = value
    path = tmp_path / "rig.toml"
    path.write_text(tomli_w.dumps(data))
    return load_rig(path)


def test_warnings_where_a_rig_limit_is_broken(tmp_path, rig):
    one = conditions([(0.359, 2.0, 6.0, 0.0)])
    assert plan(rig, linear(), one)["warnings"][0] == []
    assert "coupling limit" in "; ".join(plan(rig, linear(k=100.0, d=0.5), one)["warnings"][0])
    assert "shorter than 3/4 period" in "; ".join(plan(rig, linear(), one, duration_s=0.01)["warnings"][0])
    small_sensor = _rig(tmp_path, **{"sensors.torque.range_nm": 100.0, "sensors.impact_force.range_n": 1000.0})
    w = "; ".join(plan(small_sensor, linear(), one)["warnings"][0])
    assert "torque" in w and "impact force" in w
    slow = _rig(tmp_path, **{"sensors.sample_rate_hz": 1000.0, "simulation.steps_per_sample": 40,
                             "sensors.pre_trigger_s": 0.02})
    assert "samples per period" in "; ".join(plan(slow, linear(k=2e5, d=20.0), one)["warnings"][0])
    odd = conditions([(0.2, 1.5, 1.0, 0.0)])
    w = "; ".join(plan(rig, linear(), odd)["warnings"][0])
    assert "not a lever fixture" in w and "not one of the rig's" in w
    double = conditions([(0.1557, 2.0, 1.0, 0.0)])
    assert "double impact" in "; ".join(plan(rig, linear(), double)["warnings"][0])


@pytest.mark.slow
def test_plan_agrees_with_simulated_and_extracted_tests_under_preload(rig, tmp_path):
    """Every condition of Table 2 (3 cases x 10 heights x 3 preloads) on the reference coupling:
    the planner's frequency within 2 % and damping ratio within 5 % of the test simulated on the
    rig (pymunk impact, sensors, log) and extracted, preloaded or not."""
    from droptower.extract import Settings, extract_file
    from droptower.rig import simulate

    coupling = load_coupling("rapp2022_nr60")
    cond = load_doe("rapp2022_table2").conditions()[["inertia_kgm2", "drop_mass_kg", "drop_height_m", "preload_nm"]]
    planned = plan(rig, coupling, cond)
    tests = cond.assign(repeat=0, seed=np.arange(len(cond)) + 1)
    measured = []
    for i, result in enumerate(simulate(rig, coupling, tests, duration_s=0.12)):
        _, extracted = extract_file(result.write_log(tmp_path / f"t{i}.parquet"), Settings())
        measured.append((extracted.frequency_hz, extracted.damping_ratio))
    f, d = np.array(measured).T
    assert np.max(np.abs(planned["frequency_hz"] / f - 1)) <= 0.02
    assert np.max(np.abs(planned["damping_ratio"] / d - 1)) <= 0.05
