"""``droptower simulate`` and ``droptower plan``: outputs, files, and one-line errors with exit code 2."""
import json

import pandas as pd
import pytest
import tomli_w

from droptower.cli.main import main
from droptower.configs import preset_dir, read_toml
from droptower.io.droptower_log import read_log
from pictures import assert_drawn

LINEAR = {"name": "linear14k", "element": [{"kind": "spring", "stiffness": 14000.0},
                                           {"kind": "dashpot", "damping": 15.55}]}


@pytest.fixture()
def coupling(tmp_path):
    path = tmp_path / "linear.toml"
    path.write_text(tomli_w.dumps(LINEAR))
    return str(path)


def run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_simulate_json_log_and_plot(tmp_path, capsys, coupling):
    log, png = tmp_path / "t.parquet", tmp_path / "t.png"
    code, out, err = run(capsys, "simulate", "--coupling", coupling, "--inertia-kgm2", "0.359", "--drop-mass-kg", "2",
                         "--height-m", "1.0", "--preload-nm", "500", "--duration-s", "0.05", "--seed", "3",
                         "--out", str(log), "--plot", str(png), "--json")
    assert code == 0, err
    s = json.loads(out)
    for key in ("drop_mass_velocity_after_m_per_s", "lever_tip_velocity_after_m_per_s", "impact_energy_j", "contacts",
                "double_impact", "max_angle_deg", "max_torque_nm", "energy_balance_error_fraction", "impact_impulse_n_s"):
        assert key in s
    assert s["lever_tip_velocity_after_m_per_s"] == pytest.approx(s["predicted_lever_tip_velocity_after_m_per_s"],
                                                                  rel=0.01)
    assert s["contacts"] >= 1 and s["double_impact"] is False and s["energy_balance_error_fraction"] < 0.01
    record = read_log(log)
    assert record.metadata["seed"] == 3 and record.metadata["preload_nm"] == 500.0
    assert_drawn(png)


def test_simulate_table_on_the_shipped_presets(capsys):
    code, out, err = run(capsys, "simulate", "--inertia-kgm2", "0.1557", "--drop-mass-kg", "2", "--height-m", "0.4",
                         "--duration-s", "0.03")
    assert code == 0, err
    assert "rapp2022_nr60 on rapp2022" in out and "2 contact(s) of drop mass and lever" in out
    assert "double impact (a second contact within the first period" in out and "): yes" in out
    assert "warning: double impact" in err


@pytest.mark.parametrize("args, words", [
    (["--drop-mass-kg", "0"], ["--drop-mass-kg: must be > 0, got 0"]),
    (["--inertia-kgm2", "-0.3"], ["--inertia-kgm2: must be > 0, got -0.3"]),
    (["--height-m", "-1"], ["--height-m: must be > 0, got -1"]),
    (["--height-m", "8"], ["--height-m", "of rig rapp2022 (field drop_height_range_m)"]),  # the preset by its name
    (["--preload-nm", "5000"], ["--preload-nm", "preload_range_nm"]),
    (["--duration-s", "0"], ["--duration-s"]),
])
def test_simulate_bad_values(capsys, coupling, args, words):
    base = {"--inertia-kgm2": "0.359", "--drop-mass-kg": "2", "--height-m": "1"}
    base.update(dict(zip(args[::2], args[1::2])))
    argv = ["simulate", "--coupling", coupling] + [x for kv in base.items() for x in kv]
    code, out, err = run(capsys, *argv)
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and "Traceback" not in err
    for w in words:
        assert w in err


def test_old_flag_names_are_hidden_aliases(capsys, coupling):
    """The names of release 0.1 keep working for one release, but --help shows only the unit names."""
    new = run(capsys, "simulate", "--coupling", coupling, "--inertia-kgm2", "0.359", "--drop-mass-kg", "2",
              "--height-m", "0.5", "--duration-s", "0.03", "--json")
    old = run(capsys, "simulate", "--coupling", coupling, "--inertia", "0.359", "--drop-mass", "2",
              "--height", "0.5", "--duration-s", "0.03", "--json")
    assert new[0] == old[0] == 0 and json.loads(new[1]) == json.loads(old[1])
    code, out, err = run(capsys, "simulate", "--coupling", coupling, "--inertia", "0.359", "--inertia-kgm2", "0.5",
                         "--drop-mass-kg", "2", "--height-m", "0.5")
    assert code == 2 and "given twice" in err
    code, out, err = run(capsys, "simulate", "--coupling", coupling, "--drop-mass-kg", "2", "--height-m", "0.5")
    assert code == 2 and "--inertia-kgm2" in err and "Missing option" in err
    code, out, _ = run(capsys, "simulate", "--help")
    assert "--inertia-kgm2" in out and "--inertia " not in out and "--height " not in out


def test_simulate_too_coarse_step_names_rig_file_and_field(tmp_path, capsys, coupling):
    data = read_toml(preset_dir("rigs") / "rapp2022.toml")
    data["simulation"]["steps_per_sample"] = 1
    data["sensors"]["sample_rate_hz"] = 500.0
    rig = tmp_path / "slow_rig.toml"
    rig.write_text(tomli_w.dumps(data))
    code, out, err = run(capsys, "simulate", "--rig", str(rig), "--coupling", coupling, "--inertia-kgm2", "0.1557",
                         "--drop-mass-kg", "1", "--height-m", "1")
    assert code == 2 and err.count("\n") == 1
    assert str(rig) in err and "simulation.steps_per_sample" in err


def test_plan_table_csv_json_plot(tmp_path, capsys, coupling):
    doe = tmp_path / "plan.toml"
    doe.write_text(tomli_w.dumps({"heights_m": [0.2, 1.8], "preloads_nm": [0.0, 1000.0], "repeats": 2, "group": [
        {"name": "case 1", "inertia_kgm2": 0.1557, "drop_mass_kg": 1.0},
        {"name": "wrong mass", "inertia_kgm2": 0.1557, "drop_mass_kg": 2.0}]}))
    csv, png = tmp_path / "plan.csv", tmp_path / "plan.png"
    code, out, err = run(capsys, "plan", "--coupling", coupling, "--doe", str(doe), "--out", str(csv),
                         "--plot", str(png))
    assert code == 0, err
    assert "4 condition(s) double-impact" in out
    table = pd.read_csv(csv)
    assert len(table) == 8 and table["double_impact"].tolist() == [False] * 4 + [True] * 4
    assert_drawn(png)
    code, out, err = run(capsys, "plan", "--coupling", coupling, "--doe", str(doe), "--json")
    rows = json.loads(out)
    assert len(rows) == 8 and all("first_period_frequency_hz" in r and "warnings" in r for r in rows)


def test_plan_bad_doe_is_one_line(tmp_path, capsys, coupling):
    doe = tmp_path / "bad.toml"
    doe.write_text(tomli_w.dumps({"heights_m": [0.2], "hieghts_m": [1.0],
                                  "group": [{"inertia_kgm2": 0.1557, "drop_mass_kg": 1.0}]}))
    code, out, err = run(capsys, "plan", "--coupling", coupling, "--doe", str(doe))
    assert code == 2 and err.count("\n") == 1 and str(doe) in err and "hieghts_m" in err
    doe.write_text(tomli_w.dumps({"heights_m": [0.2, 7.0], "group": [{"inertia_kgm2": 0.1557, "drop_mass_kg": 1.0}]}))
    code, out, err = run(capsys, "plan", "--coupling", coupling, "--doe", str(doe))
    assert code == 2 and str(doe) in err and "heights_m" in err
