"""Rig and test-plan files: presets, expansion to tests, one-line errors naming file and field."""
from pathlib import Path

import pytest
import tomli_w

from droptower.configs import preset_dir, read_toml
from droptower.errors import DroptowerError
from droptower.rig.config import load_doe, load_rig


def _write(tmp_path: Path, name: str, data: dict) -> Path:
    path = tmp_path / name
    path.write_text(tomli_w.dumps(data))
    return path


def test_rapp2022_rig_matches_table_1():
    rig = load_rig("rapp2022")
    assert rig.lever_length_m == 0.2
    assert rig.inertias_kgm2 == [0.1557, 0.359, 0.5233]
    assert rig.drop_masses_kg == [1.0, 2.0]
    assert rig.drop_height_range_m == [0.005, 6.0]
    assert rig.preload_range_nm == [0.0, 1000.0]
    assert rig.coupling_limit_deg == 28.0
    assert rig.restitution == 0.5
    assert rig.sensors.sample_rate_hz == 38400.0
    assert rig.sensors.impact_force.contact_duration_s == pytest.approx(3e-4)
    assert rig.dt_s == pytest.approx(1 / 38400 / rig.simulation.steps_per_sample)


def test_table2_plan_has_450_tests():
    doe = load_doe("rapp2022_table2")
    tests = doe.tests()
    assert len(tests) == 3 * 10 * 3 * 5 == 450
    assert list(tests.columns) == ["test_id", "case", "inertia_kgm2", "drop_mass_kg", "drop_height_m", "preload_nm",
                                   "repeat", "seed"]
    assert tests["seed"].is_unique
    combos = set(zip(tests["inertia_kgm2"], tests["drop_mass_kg"]))
    assert combos == {(0.1557, 1.0), (0.359, 2.0), (0.5233, 2.0)}
    assert sorted(tests["drop_height_m"].unique()) == [0.05, 0.2, 0.4, 0.55, 0.7, 1.0, 1.4, 1.8, 3.5, 6.0]
    assert sorted(tests["preload_nm"].unique()) == [0.0, 500.0, 1000.0]
    assert sorted(tests["repeat"].unique()) == [0, 1, 2, 3, 4]
    cond = doe.conditions()
    assert len(cond) == 90 and (cond["repeats"] == 5).all()
    doe.check(load_rig("rapp2022"))


def test_group_overrides(tmp_path):
    path = _write(tmp_path, "plan.toml", {"heights_m": [0.1, 0.2], "group": [
        {"inertia_kgm2": 0.3, "drop_mass_kg": 1.0},
        {"name": "x", "inertia_kgm2": 0.4, "drop_mass_kg": 2.0, "heights_m": [1.0], "repeats": 3}]})
    tests = load_doe(path).tests()
    assert len(tests) == 2 + 3
    assert list(tests["case"]) == ["group 1", "group 1", "x", "x", "x"]


def test_unknown_field_in_doe_names_file_and_field(tmp_path):
    data = read_toml(preset_dir("doe") / "rapp2022_table2.toml")
    data["group"][1]["drop_mas_kg"] = 2.0
    path = _write(tmp_path, "bad.toml", data)
    with pytest.raises(DroptowerError) as err:
        load_doe(path)
    msg = err.value.message
    assert str(path) in msg and "group 2 (case 2)" in msg and "drop_mas_kg" in msg and "unknown field" in msg
    assert "\n" not in msg


@pytest.mark.parametrize("field, value, words", [
    ("lever_length_m", 0.0, "lever_length_m"),
    ("restitution", 1.5, "restitution"),
    ("colour", "red", "colour"),
])
def test_bad_rig_field_names_file_and_field(tmp_path, field, value, words):
    data = read_toml(preset_dir("rigs") / "rapp2022.toml")
    data[field] = value
    path = _write(tmp_path, "rig.toml", data)
    with pytest.raises(DroptowerError) as err:
        load_rig(path)
    assert str(path) in err.value.message and words in err.value.message


def test_pre_trigger_longer_than_the_shortest_fall_is_an_error(tmp_path):
    data = read_toml(preset_dir("rigs") / "rapp2022.toml")
    data["sensors"]["pre_trigger_s"] = 0.05
    path = _write(tmp_path, "rig.toml", data)
    with pytest.raises(DroptowerError, match="pre_trigger_s"):
        load_rig(path)


@pytest.mark.parametrize("args, field", [
    ((0.359, -2.0, 1.0, 0.0), "drop_mass_kg"),
    ((0.0, 2.0, 1.0, 0.0), "inertia_kgm2"),
    ((0.359, 2.0, 0.0, 0.0), "drop_height_m"),
    ((0.359, 2.0, 6.5, 0.0), "drop_height_m"),
    ((0.359, 2.0, 1.0, 2000.0), "preload_nm"),
])
def test_check_test_rejects_what_the_rig_cannot_do(args, field):
    rig = load_rig("rapp2022")
    with pytest.raises(DroptowerError) as err:
        rig.check_test(*args, where="test 3")
    assert err.value.where == f"test 3: {field}"


def test_doe_outside_the_rig_range_names_the_group(tmp_path):
    path = _write(tmp_path, "plan.toml", {"heights_m": [0.1, 9.0], "group": [{"inertia_kgm2": 0.3, "drop_mass_kg": 1.0}]})
    with pytest.raises(DroptowerError) as err:
        load_doe(path).check(load_rig("rapp2022"))
    assert str(path) in err.value.message and "group 1: heights_m" in err.value.message
