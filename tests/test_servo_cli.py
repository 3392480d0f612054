"""``droptower servo``: JSON keys and values, table, plot, one-line errors with exit code 2."""
import json
import math

import numpy as np
import pytest

from droptower.cli.main import main
from droptower.servo import run_grid

KV = 'name = "kv"\n[[element]]\nkind = "spring"\nstiffness = 12000.0\n[[element]]\nkind = "dashpot"\ndamping = 15.0\n'

KEYS = {"amplitude_deg", "frequency_hz", "storage_stiffness_nm_per_rad", "loss_stiffness_nm_per_rad",
        "dynamic_stiffness_nm_per_rad", "dynamic_stiffness_nm_per_deg", "loss_factor", "loss_angle_deg",
        "relative_damping_psi", "damping_work_j", "preload_nm", "drop_tower_equivalent_damping_ratio"}


@pytest.fixture
def kv_file(tmp_path):
    path = tmp_path / "kv.toml"
    path.write_text(KV)
    return path


def test_json_keys_and_values(kv_file, capsys):
    code = main(["servo", str(kv_file), "--amplitude-deg", "0.5,1.5", "--frequency-hz", "2,20", "--json"])
    out = capsys.readouterr().out
    assert code == 0
    rows = json.loads(out)
    assert len(rows) == 4
    assert all(KEYS <= set(r) for r in rows)
    assert sorted((r["amplitude_deg"], r["frequency_hz"]) for r in rows) == [(0.5, 2), (0.5, 20), (1.5, 2), (1.5, 20)]
    for r in rows:  # Kelvin-Voigt: K' = k, K'' = c omega, |K*| per degree = per radian * pi/180
        assert r["storage_stiffness_nm_per_rad"] == pytest.approx(12000.0, rel=2e-3)
        assert r["loss_stiffness_nm_per_rad"] == pytest.approx(15.0 * 2 * math.pi * r["frequency_hz"], rel=2e-3)
        assert r["dynamic_stiffness_nm_per_deg"] == pytest.approx(r["dynamic_stiffness_nm_per_rad"] * math.pi / 180)
        assert r["preload_nm"] == 0.0
    # the CLI reports what the API computes
    api = run_grid(kv_file, np.radians([0.5, 1.5]), [2.0, 20.0])
    np.testing.assert_allclose(sorted(r["relative_damping_psi"] for r in rows), sorted(api["relative_damping_psi"]))


def test_table_and_plot(kv_file, tmp_path, capsys):
    png = tmp_path / "loops.png"
    code = main(["servo", str(kv_file), "--amplitude-deg", "1", "--frequency-hz", "5,10", "--plot", str(png)])
    out = capsys.readouterr().out
    assert code == 0
    assert "dynamic_stiffness_nm_per_deg" in out and "relative_damping_psi" in out
    assert len(out.strip().splitlines()) == 2 + 2  # title, header, one line per grid point
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_preload_option(kv_file, capsys):
    code = main(["servo", str(kv_file), "--amplitude-deg", "0.5", "--frequency-hz", "5", "--preload-nm", "240",
                 "--json"])
    (row,) = json.loads(capsys.readouterr().out)
    assert code == 0
    assert row["mean_torque_nm"] == pytest.approx(240.0, abs=0.03)
    assert row["offset_rad"] == pytest.approx(240.0 / 12000.0, rel=1e-4)


@pytest.mark.parametrize("args,match", [
    (["--amplitude-deg", "0.5,x"], "--amplitude-deg"),
    (["--amplitude-deg", "0.5,,1"], "--amplitude-deg"),
    (["--frequency-hz", "-3"], "--frequency-hz"),
    (["--frequency-hz", "10,150"], "too coarse"),
    (["--sample-rate-hz", "100", "--frequency-hz", "10"], "too coarse"),
])
def test_bad_input_is_one_line_exit_2(kv_file, capsys, args, match):
    code = main(["servo", str(kv_file)] + args)
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert len(err.splitlines()) == 1 and match in err


def test_missing_coupling_is_exit_2(tmp_path, capsys):
    code = main(["servo", str(tmp_path / "nope.toml")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and "nope.toml" in err


def test_translational_coupling_in_mm_and_n(tmp_path, capsys):
    """A translational Kelvin-Voigt mount (k in N/m, c in N*s/m): driven by --amplitude-mm, its
    fields named for it, K' = k and K'' = c omega; torsional options refused for it."""
    path = tmp_path / "mount.toml"
    path.write_text('name = "mount"\nunits = "translational"\n' + KV.split("\n", 1)[1])
    code = main(["servo", str(path), "--amplitude-mm", "0.2,1", "--frequency-hz", "2,20", "--preload-n", "0",
                 "--json"])
    rows = json.loads(capsys.readouterr().out)
    assert code == 0 and len(rows) == 4
    assert {"amplitude_mm", "preload_n", "storage_stiffness_n_per_m", "loss_stiffness_n_per_m",
            "dynamic_stiffness_n_per_mm", "loss_angle_deg", "offset_mm"} <= set(rows[0])
    assert not any(token in key.split("_") for r in rows for key in r if not key.startswith("loss_angle")
               for token in ("nm", "rad", "deg", "torque", "angle"))
    assert sorted((r["amplitude_mm"], r["frequency_hz"]) for r in rows) == [(0.2, 2), (0.2, 20), (1, 2), (1, 20)]
    for r in rows:
        assert r["storage_stiffness_n_per_m"] == pytest.approx(12000.0, rel=2e-3)
        assert r["loss_stiffness_n_per_m"] == pytest.approx(15.0 * 2 * math.pi * r["frequency_hz"], rel=2e-3)
        assert r["dynamic_stiffness_n_per_mm"] == pytest.approx(r["dynamic_stiffness_n_per_m"] / 1e3)
        assert r["force_amplitude_n"] == pytest.approx(r["dynamic_stiffness_n_per_m"] * r["amplitude_mm"] / 1e3,
                                                       rel=2e-3)
    assert main(["servo", str(path), "--amplitude-deg", "1"]) == 2
    assert "translational coupling: give --amplitude-mm" in capsys.readouterr().err
    assert main(["servo", "rapp2022_nr60", "--amplitude-mm", "1"]) == 2
    assert "torsional coupling: --amplitude-mm is for translational ones" in capsys.readouterr().err
