"""``droptower extract``: batch evaluation of log files, outputs, and bad input."""
from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from droptower.cli.main import main
from droptower.extract.synthetic import SyntheticDrop
from droptower.io.droptower_log import write_log

REQUIRED = ("file", "frequency_hz", "amplitude_deg", "stiffness_nm_per_rad", "stiffness_nm_per_deg", "damping_ratio",
            "stiffness_torque_nm_per_deg", "loss_factor", "relative_damping_psi", "double_impact", "fit_error", "flags",
            "stiffness_nm_per_rad_std", "damping_ratio_std", "frequency_hz_std")


@pytest.fixture
def logs(tmp_path):
    drops = {
        "fast.csv": SyntheticDrop(ringing_fraction=0.3, preload_nm=500.0, seed=1),
        "slow.parquet": SyntheticDrop(sample_rate_hz=2048.0, damping_ratio=1.1, seed=2),
        "double.csv": SyntheticDrop(second_impact_after_s=0.012, seed=3),
    }
    return {name: (drop.write(tmp_path / name), drop) for name, drop in drops.items()}


def _bad_log(tmp_path, name, change):
    drop = SyntheticDrop(sample_rate_hz=2048.0, seed=4)
    time, channels = drop.channels()
    time, channels = change(time.copy(), {k: v.copy() for k, v in channels.items()})
    return write_log(tmp_path / name, time, channels, drop.metadata())


def test_json_rows(logs, capsys):
    assert main(["extract", *[str(p) for p, _ in logs.values()], "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert len(rows) == 3
    for row, (path, drop) in zip(rows, logs.values()):
        assert set(REQUIRED) <= set(row)
        assert row["file"] == str(path)
        assert row["stiffness_nm_per_rad"] == pytest.approx(drop.stiffness_nm_per_rad, rel=0.01 if not
                                                            drop.second_impact_after_s else 1.0)
        assert row["stiffness_nm_per_deg"] == pytest.approx(row["stiffness_nm_per_rad"] * np.pi / 180)
        assert row["preload_nm"] == drop.preload_nm  # the test's metadata
        assert row["double_impact"] == (drop.second_impact_after_s is not None)
    assert rows[0]["damping_ratio"] == pytest.approx(1.5, rel=0.03)
    assert rows[1]["damping_ratio"] == pytest.approx(1.1, rel=0.03)
    assert "double_impact" in rows[2]["flags"]


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_out_table_and_plots(logs, tmp_path, suffix):
    out, plots = tmp_path / f"results{suffix}", tmp_path / "plots"
    assert main(["extract", *[str(p) for p, _ in logs.values()], "--out", str(out), "--plot", str(plots)]) == 0
    table = pd.read_csv(out) if suffix == ".csv" else pd.read_parquet(out)
    assert len(table) == 3 and set(REQUIRED) <= set(table.columns)
    assert table.loc[2, "flags"] == "double_impact"
    assert table.loc[0, "torque_offset_nm"] == pytest.approx(515.0, abs=1.0)
    assert sorted(p.name for p in plots.iterdir()) == ["double.png", "fast.png", "slow.png"]
    assert not list(tmp_path.glob(".*.tmp"))  # written atomically, nothing left over


def test_no_duplicated_metadata_columns(logs, tmp_path, capsys):
    """The log's inertia is the inertia used: one column. Overridden, the log's value is kept
    beside it under its own name (it differs), never twice the same value."""
    path, drop = logs["fast.csv"]
    out = tmp_path / "r.csv"
    assert main(["extract", str(path), "--out", str(out)]) == 0
    table = pd.read_csv(out)
    assert table.loc[0, "inertia_kgm2"] == drop.metadata()["inertia_kgm2"]
    assert not [c for c in table.columns if c.startswith(("meta_", "log_"))]
    assert main(["extract", str(path), "--out", str(out), "--inertia-kgm2", "0.5"]) == 0
    table = pd.read_csv(out)
    assert table.loc[0, "inertia_kgm2"] == 0.5 and table.loc[0, "log_inertia_kgm2"] == drop.metadata()["inertia_kgm2"]


def test_single_file_error_printed_once(tmp_path, capsys):
    path = tmp_path / "empty.csv"
    path.write_text("")
    assert main(["extract", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count(str(path)) == 1 and "failed" not in err


def test_rig_values_on_the_command_line(tmp_path, capsys):
    drop = SyntheticDrop(seed=5)
    meta = {k: v for k, v in drop.metadata().items() if k not in ("inertia_kgm2", "lever_length_m")}
    time, channels = drop.channels()
    path = write_log(tmp_path / "bare.csv", time, channels, meta)
    assert main(["extract", str(path), "--json"]) == 2
    assert "no rotating inertia" in capsys.readouterr().err
    assert main(["extract", str(path), "--inertia-kgm2", "0.359", "--lever-length-m", "0.2", "--json"]) == 0
    row = json.loads(capsys.readouterr().out)[0]
    assert row["stiffness_nm_per_rad"] == pytest.approx(drop.stiffness_nm_per_rad, rel=0.01)
    assert row["lever_rate_after_rad_per_s"] == pytest.approx(drop.impact_velocity_rad_per_s, rel=0.02)


def test_channel_mapping_with_units(tmp_path, capsys):
    drop = SyntheticDrop(seed=6)
    time, ch = drop.channels()
    path = write_log(tmp_path / "lab.csv", time * 1e3, {"Winkel_deg": np.degrees(ch["angle_rad"]),
                                                        "Md_knm": ch["torque_nm"] / 1e3,
                                                        "Kraft_kn": ch["impact_force_n"] / 1e3}, drop.metadata())
    code = main(["extract", str(path), "--json", "--channel", "time=time_s:ms", "--channel", "angle=Winkel_deg:deg",
                 "--channel", "torque=Md_knm:kN*m", "--channel", "impact_force=Kraft_kn:kN"])
    assert code == 0, capsys.readouterr().err
    row = json.loads(capsys.readouterr().out)[0]
    assert row["stiffness_nm_per_rad"] == pytest.approx(drop.stiffness_nm_per_rad, rel=0.01)
    assert row["stiffness_torque_nm_per_deg"] == pytest.approx(drop.stiffness_nm_per_rad * np.pi / 180, rel=0.02)


BAD = {
    "constant.csv": (lambda t, c: (t, {**c, "angle_rad": np.full_like(t, 0.01)}), "constant signal"),
    "noimpact.csv": (lambda t, c: (t, {**c, "impact_force_n": np.random.default_rng(1).normal(0, 20, t.size)}),
                     "no impact found"),
    "short.csv": (lambda t, c: (t[:82], {k: v[:82] for k, v in c.items()}), "less than 3/4 of the oscillation period"),
    "gap.csv": (lambda t, c: (t, {**c, "angle_rad": np.where((t > 0.05) & (t < 0.06), np.nan, c["angle_rad"])}), "NaN"),
    "backwards.csv": (lambda t, c: (np.where(np.arange(t.size) == 200, t[150], t), c), "non-monotonic"),
    "noangle.csv": (lambda t, c: (t, {k: v for k, v in c.items() if k != "angle_rad"}), "no angle channel"),
}


@pytest.mark.parametrize("name", BAD)
def test_bad_input_one_line(tmp_path, capsys, name):
    change, message = BAD[name]
    path = _bad_log(tmp_path, name, change)
    assert main(["extract", str(path)]) == 2
    err = capsys.readouterr().err.splitlines()
    first = err[0]
    assert first.startswith(f"droptower: error: {path}") and message in first
    assert "Traceback" not in "\n".join(err)


def test_missing_mapped_channel(logs, capsys):
    path, _ = logs["fast.csv"]
    assert main(["extract", str(path), "--channel", "torque=Drehmoment"]) == 2
    assert "no channel 'Drehmoment'" in capsys.readouterr().err


def test_batch_with_a_bad_file_writes_the_good_ones(logs, tmp_path, capsys):
    bad = _bad_log(tmp_path, "noimpact.csv", BAD["noimpact.csv"][0])
    good = [str(p) for p, _ in logs.values()]
    out = tmp_path / "results.csv"
    code = main(["extract", good[0], str(bad), good[1], str(tmp_path / "missing.csv"), "--out", str(out)])
    assert code != 0
    err = capsys.readouterr().err
    assert "2 of 4 file(s) failed" in err and "missing.csv: no such file" in err
    assert list(pd.read_csv(out)["file"]) == [good[0], good[1]]


@pytest.mark.parametrize("args, message", [
    (["--window", "fist-cycle"], "window 'fist-cycle'"),
    (["--out", "results.txt"], "unknown table format"),
    (["--inertia-kgm2", "-1"], "--inertia-kgm2: must be > 0"),
    (["--channel", "angel=x"], "unknown role"),
])
def test_bad_options_exit_2(logs, capsys, args, message):
    path, _ = logs["fast.csv"]
    assert main(["extract", str(path), *args]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1


def test_rig_gives_laser_radius_and_lever_length(tmp_path, capsys):
    """A laser distance channel is turned into the angle with the rig's sensor radius."""
    from droptower.rig.config import load_rig

    rig = load_rig("rapp2022")
    drop = SyntheticDrop(inertia_kgm2=rig.inertias_kgm2[2], seed=7)
    time, ch = drop.channels()
    meta = {k: v for k, v in drop.metadata().items() if k != "lever_length_m"}
    path = write_log(tmp_path / "laser.csv", time, {"laser_distance_m": ch["angle_rad"] * rig.sensors.laser.radius_m,
                                                    "torque_nm": ch["torque_nm"],
                                                    "impact_force_n": ch["impact_force_n"]}, meta)
    assert main(["extract", str(path), "--json"]) == 2  # no sensor radius
    assert "needs the laser spot radius (m): the log carries no 'laser_radius_m'; give --sensor-radius-m or --rig" \
        in capsys.readouterr().err
    assert main(["extract", str(path), "--rig", "rapp2022", "--json"]) == 0
    row = json.loads(capsys.readouterr().out)[0]
    assert row["stiffness_nm_per_rad"] == pytest.approx(drop.stiffness_nm_per_rad, rel=0.01)
    assert row["lever_rate_after_rad_per_s"] == pytest.approx(drop.impact_velocity_rad_per_s, rel=0.02)


def test_the_logs_own_laser_radius_lever_and_inertia_are_used(tmp_path, capsys):
    """A droptower log whose angle channel was removed still carries laser_radius_m, inertia_kgm2
    and lever_length_m: extract needs no flag for them (and a flag overrides them)."""
    drop = SyntheticDrop(inertia_kgm2=0.359, seed=3)
    time, ch = drop.channels()
    radius = 0.15
    meta = {**drop.metadata(), "laser_radius_m": radius, "lever_length_m": 0.2}
    path = write_log(tmp_path / "no_angle.csv", time, {"laser_distance_m": radius * np.tan(ch["angle_rad"]),
                                                       "torque_nm": ch["torque_nm"],
                                                       "impact_force_n": ch["impact_force_n"]}, meta)
    assert main(["extract", str(path), "--json"]) == 0
    row = json.loads(capsys.readouterr().out)[0]
    assert row["stiffness_nm_per_rad"] == pytest.approx(drop.stiffness_nm_per_rad, rel=0.01)
    assert row["lever_rate_after_rad_per_s"] == pytest.approx(drop.impact_velocity_rad_per_s, rel=0.02)
    assert row["lever_rate_after_from"] == "impact_force"  # the log's lever length was used
    # a given radius overrides the log's: twice the radius reads about half the angle
    assert main(["extract", str(path), "--sensor-radius-m", str(2 * radius), "--json"]) == 0
    halved = json.loads(capsys.readouterr().out)[0]
    assert halved["amplitude_deg"] == pytest.approx(row["amplitude_deg"] / 2, rel=0.02)



@pytest.mark.parametrize("decimals", [4, 5])
def test_time_printed_with_few_decimals_extracts_as_the_exact_log(tmp_path, capsys, decimals):
    """A lab export's time column with 4 or 5 decimals at 2048 Hz: a constant rate rounded for
    printing (steps 0.0004 / 0.0005 s), evaluated exactly as the log with exact stamps; a
    truly irregular time base is refused."""
    exact = _bad_log(tmp_path, "exact.csv", lambda t, c: (t, c))
    rounded = _bad_log(tmp_path, "rounded.csv", lambda t, c: (np.round(t, decimals), c))
    assert main(["extract", str(exact), str(rounded), "--json"]) == 0
    captured = capsys.readouterr()
    a, b = json.loads(captured.out)
    assert set(a) == set(b)
    for key in set(a) - {"file"}:  # stamps t0 + i / rate: equal to round-off
        assert b[key] == (pytest.approx(a[key], rel=1e-8, abs=1e-15) if isinstance(a[key], float) else a[key]), key
    assert f"rounded.csv: time stamps printed to {decimals} decimals" in captured.err
    assert "constant 2048 Hz estimated from the whole record" in captured.err

    def jitter(t, c):
        t[200:] += 0.3 / 2048.0
        return t, c

    irregular = _bad_log(tmp_path, "irregular.csv", jitter)
    assert main(["extract", str(irregular)]) == 2
    err = capsys.readouterr().err
    assert "irregular.csv" in err and "the time step is not constant" in err and "Traceback" not in err
