"""``droptower channels``: table, JSON with unit-suffixed keys, one-line errors with exit code 2."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from droptower.cli.main import main
from droptower.io import write_log

REFERENCE = Path(__file__).resolve().parent / "data" / "catman"  # shipped test data (MIT, see its LICENSE.txt)


def test_channels_json_own_log(tmp_path, capsys):
    time = np.arange(5) / 1000.0
    path = write_log(tmp_path / "d.csv", time, {"angle_rad": np.array([0, 1, np.nan, 3, 4.5])}, {})
    assert main(["channels", str(path), "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert [r["name"] for r in rows] == ["time_s", "angle_rad"]
    angle = rows[1]
    assert angle == {"name": "angle_rad", "unit": "rad", "samples": 5, "sample_rate_hz": pytest.approx(1000.0),
                     "first_time_s": 0.0, "last_time_s": 0.004, "first_value": 0.0, "last_value": 4.5,
                     "invalid_markers": 0, "nan": 1, "role": "angle", "servo_role": "angle"}
    assert rows[0]["role"] == "time"


def test_channels_table_catman(capsys):
    path = REFERENCE / "2byteJob1_2022_04_12_13_32_10.bin"
    assert main(["channels", str(path)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert "catman binary, 10 channels" in out[0]
    assert out[1].split()[:4] == ["name", "unit", "samples", "rate_hz"]
    thermo = next(line for line in out if line.startswith("Thermocouple Type K"))
    assert thermo.split()[-4:] == ["100", "0", "-", "-"]  # 100 invalid markers, no NaN, no roles
    poti = next(line for line in out if line.startswith("poti5k "))
    assert poti.split()[1:4] == ["Ohm", "100", "300"] and "0.65018" in poti
    assert main(["channels", str(path), "--json"]) == 0
    rows = {r["name"]: r for r in json.loads(capsys.readouterr().out)}
    assert rows["Thermocouple Type K"]["invalid_markers"] == 100 and rows["poti5k"]["sample_rate_hz"] == 300.0


def test_channels_of_a_translational_lab_export(tmp_path, capsys):
    """A damper's servo record as exported (time printed to 4 decimals at 1024 Hz, inches and
    kips): the rate behind the rounded stamps and the servo roles identify would give."""
    path = tmp_path / "damper.csv"
    t = np.arange(64) / 1024.0
    lines = ["time [s],displacement [in],force [kip]"] + [f"{x:.4f},{0.01 * np.sin(40 * x):.10g},{np.cos(40 * x):.10g}"
                                                         for x in t]
    path.write_text("\n".join(lines) + "\n")
    assert main(["channels", str(path), "--json"]) == 0
    rows = {r["name"]: r for r in json.loads(capsys.readouterr().out)}
    assert rows["displacement"]["sample_rate_hz"] == 1024.0
    assert {n: r["servo_role"] for n, r in rows.items()} == {"time": "time", "displacement": "displacement",
                                                             "force": "force"}
    assert main(["channels", str(path)]) == 0
    assert "servo record: translational (displacement and force)" in capsys.readouterr().out
    assert main(["channels", str(path), "--channel", "angle=displacement"]) == 0
    assert "servo record: torsional (angle and torque; no torque channel found)" in capsys.readouterr().out


def test_channels_csv_time_base_suffix_units_and_roles(tmp_path, capsys):
    """A lab CSV (';', decimal comma): the rate and time span come from its time column, a unit
    from a name suffix (angle_deg), and each channel shows the role extract would give it."""
    path = tmp_path / "lab.csv"
    t = np.arange(8) / 2000.0
    lines = ["Zeit [ms];angle_deg;Md [kN*m];torque_nm"] + [
        f"{1e3 * x:.1f};{x:.6f};{2 * x:.6f};{3 * x:.6f}".replace(".", ",") for x in t]
    path.write_text("\n".join(lines) + "\n")
    assert main(["channels", str(path), "--json"]) == 0
    rows = {r["name"]: r for r in json.loads(capsys.readouterr().out)}
    assert rows["angle_deg"]["unit"] == "deg" and rows["torque_nm"]["unit"] == "N*m"
    assert rows["angle_deg"]["sample_rate_hz"] == pytest.approx(2000.0)
    assert rows["angle_deg"]["last_time_s"] == pytest.approx(0.0035)  # ms converted to s
    assert {n: r["role"] for n, r in rows.items()} == {"Zeit": "time", "angle_deg": "angle", "Md": None,
                                                       "torque_nm": "torque"}
    assert main(["channels", str(path), "--channel", "torque=Md"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert "time base: channel 'Zeit'" in out[0]
    assert out[1].split()[-2:] == ["role", "servo_role"] and out[4].split()[0] == "Md"
    assert out[4].split()[-2:] == ["torque", "torque"]
    assert "roles not found: impact_force" in out[-2] and out[-1] == "servo record: torsional (angle and torque)"


def test_channels_csv_options(tmp_path, capsys):
    path = tmp_path / "x.txt"
    path.write_text("note\nt;a\n0;1,5\n1;2,5\n")
    assert main(["channels", str(path), "--json", "--header-lines", "1", "--delimiter", ";", "--decimal", ","]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert [(r["name"], r["last_value"]) for r in rows] == [("t", 1.0), ("a", 2.5)]


@pytest.mark.parametrize("content, message", [
    (b"\x94\x13\x00\x80", "truncated or corrupt catman file"),
    (b"words only\nno numbers\n", "no numeric data rows"),
])
def test_channels_bad_file_exits_2_with_one_line(tmp_path, capsys, content, message):
    path = tmp_path / ("bad.bin" if content.startswith(b"\x94") else "bad.csv")
    path.write_bytes(content)
    assert main(["channels", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(path) in err and message in err
