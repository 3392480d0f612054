"""``droptower validate``: a map against servo sweeps (docs/theory.md#servo, #damping-measures, Rapp et al. 2022, Fig. 14) and
against a measured map (Table 4): closed forms on a Kelvin-Voigt coupling, measured-results
input in every accepted form, the reference comparison, and one-line errors."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from droptower import sdof
from droptower.cli.main import main
from droptower.compare import (compare_reference, compare_with_servo, read_servo_results, run_sweeps, sweep_points)
from droptower.compare.servo_points import AMPLITUDE_SWEEPS, FREQUENCY_SWEEPS
from droptower.maps import MapFit
from droptower.maps.mapfit import FitStats, MapRange
from pictures import assert_drawn

K_NM_PER_RAD, C_NMS_PER_RAD = 12000.0, 5.0      # Kelvin-Voigt: K' = k, eta = c omega / k <= 0.26
KV = f'name = "kv"\n[[element]]\nkind = "spring"\nstiffness = {K_NM_PER_RAD}\n' \
     f'[[element]]\nkind = "dashpot"\ndamping = {C_NMS_PER_RAD}\n'
K_DEG = K_NM_PER_RAD * math.pi / 180
MAP_ERROR = 0.03          # the test map's stiffness is 3 % above the coupling's
MAP_DAMPING_RATIO = 0.8   # and its damping ratio is this everywhere
RANGE = MapRange(amplitude_deg_min=0.15, amplitude_deg_max=3.2, frequency_hz_min=20.0, frequency_hz_max=60.0)


def constant_map() -> MapFit:
    """Eq. 19 = k1 (k2..k7 zero) and eq. 20 = k8: stiffness and damping ratio constant."""
    coefficients = {f"k{i}": 0.0 for i in range(1, 14)}
    coefficients["k1"] = K_DEG * (1 + MAP_ERROR)
    coefficients["k8"] = coefficients["k1"] / MAP_DAMPING_RATIO
    stats = FitStats(30, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0)
    return MapFit(coefficients=coefficients, uncertainties={k: 0.0 for k in coefficients}, stats=stats, range=RANGE,
                  source="test")


@pytest.fixture(scope="module")
def kv_file(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("kv") / "kv.toml"
    path.write_text(KV)
    return path


@pytest.fixture(scope="module")
def kv_points(kv_file):
    return run_sweeps(kv_file, reduced=True)


def servo_d(frequency_hz):
    """The drop-tower-equivalent damping ratio of the Kelvin-Voigt coupling (docs/theory.md#damping-measures)."""
    return sdof.drop_tower_equivalent_damping_ratio(C_NMS_PER_RAD * 2 * np.pi * np.asarray(frequency_hz) / K_NM_PER_RAD)


def test_sweeps_are_those_of_notes_1_6():
    points = sweep_points()
    for amplitude, f_max in FREQUENCY_SWEEPS.items():
        f = points.query("sweep == 'frequency' and amplitude_deg == @amplitude")["frequency_hz"]
        assert f.max() == f_max and f.min() <= 1.0 and f.is_monotonic_increasing and len(f) >= 6
    for frequency, a_max in AMPLITUDE_SWEEPS.items():
        a = points.query("sweep == 'amplitude' and frequency_hz == @frequency")["amplitude_deg"]
        assert a.max() == a_max and a.min() <= 0.2 and a.is_monotonic_increasing and len(a) >= 6
    assert (0.5, 100.0) in set(zip(points["amplitude_deg"], points["frequency_hz"]))
    assert (2.0, 30.0) in set(zip(points["amplitude_deg"], points["frequency_hz"]))


def test_deviations_against_closed_forms(kv_points):
    validation = compare_with_servo(constant_map(), kv_points)
    t = validation.table
    a, f = t["amplitude_deg"].to_numpy(), t["frequency_hz"].to_numpy()
    # the bench measures the Kelvin-Voigt coupling: K' = k, d from eta = c omega / k
    np.testing.assert_allclose(t["servo_stiffness_nm_per_deg"], K_DEG, rtol=2e-3)
    np.testing.assert_allclose(t["servo_damping_ratio"], servo_d(f), rtol=5e-3)
    np.testing.assert_allclose(t["stiffness_deviation_pct"], 100 * MAP_ERROR, atol=0.25)
    np.testing.assert_allclose(t["damping_deviation_pct"], 100 * (MAP_DAMPING_RATIO / servo_d(f) - 1), rtol=5e-3)
    # psi and eta alongside, both by the DIN definition of the linear coupling
    eta_map = sdof.loss_factor(sdof.decay_ratio(MAP_DAMPING_RATIO), 1.0)
    np.testing.assert_allclose(t["map_loss_factor"], eta_map)
    np.testing.assert_allclose(t["map_relative_damping_psi"], 2 * np.pi * eta_map / np.sqrt(1 + eta_map**2))
    np.testing.assert_allclose(t["servo_relative_damping_psi"],
                               2 * np.pi * t["servo_loss_factor"] / np.sqrt(1 + t["servo_loss_factor"] ** 2), rtol=2e-3)
    # inside / outside the measured range, each distinct point counted once
    inside = (a >= 0.15) & (a <= 3.2) & (f >= 20) & (f <= 60)
    assert (t["in_range"].to_numpy() == inside).all()
    distinct = t.drop_duplicates(["amplitude_deg", "frequency_hz"])
    s = validation.summary
    assert s["inside"]["n_points"] == distinct["in_range"].sum() > 0
    assert s["outside"]["n_points"] == (~distinct["in_range"]).sum() > 0
    dev = distinct.loc[distinct["in_range"], "damping_deviation_pct"]
    assert s["inside"]["damping_rms_deviation_pct"] == pytest.approx(np.sqrt(np.mean(dev**2)))
    assert s["inside"]["damping_max_deviation_pct"] == pytest.approx(np.abs(dev).max())
    assert "drop-tower-equivalent d" in s["damping_definition"] and "storage stiffness K'" in s["stiffness_definition"]


def test_cli_writes_table_figure_and_summary(kv_file, tmp_path, capsys):
    map_file = tmp_path / "map.json"
    constant_map().to_json(map_file)
    out = tmp_path / "validation"
    assert main(["validate", "--map", str(map_file), "--coupling", str(kv_file), "--quick", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "inside the hull" in text and "inside the rectangle" in text and "outside the hull" in text
    assert "drop-tower-equivalent d" in text
    for name in ("validation.csv", "validation_summary.json", "servo_results.csv"):
        assert (out / name).stat().st_size > 0
    assert_drawn(out / "fig14_servo_validation.png")
    table = pd.read_csv(out / "validation.csv")
    assert {"sweep", "in_range", "in_rectangle", "stiffness_deviation_pct", "damping_deviation_pct",
            "loss_factor_deviation_pct", "decay_ratio_deviation_pct", "servo_relative_damping_psi",
            "map_relative_damping_psi"} <= set(table.columns)
    # the bench's table reads back as measured results: the same comparison
    assert main(["validate", "--map", str(map_file), "--servo-results", str(out / "servo_results.csv"), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    again = pd.DataFrame(doc["points"])
    np.testing.assert_allclose(again["damping_deviation_pct"], table["damping_deviation_pct"], rtol=1e-9)
    np.testing.assert_allclose(again["stiffness_deviation_pct"], table["stiffness_deviation_pct"], rtol=1e-9)


def test_measured_results_in_every_accepted_form(kv_points, tmp_path):
    raw = kv_points.raw.drop_duplicates(["amplitude_deg", "frequency_hz"])
    eta = raw["loss_factor"].to_numpy()
    expected_d = sdof.drop_tower_equivalent_damping_ratio(eta)
    forms = {
        "loss_factor": raw[["amplitude_deg", "frequency_hz", "dynamic_stiffness_nm_per_rad", "loss_factor"]],
        "loss_angle_deg": raw[["amplitude_deg", "frequency_hz", "storage_stiffness_nm_per_rad", "loss_angle_deg"]],
        "relative_damping_psi": raw[["amplitude_deg", "frequency_hz", "storage_stiffness_nm_per_deg"]].assign(
            relative_damping_psi=2 * np.pi * eta / np.sqrt(1 + eta**2)),
    }
    for name, table in forms.items():
        path = tmp_path / f"{name}.parquet"
        table.to_parquet(path)
        points = read_servo_results(path)
        got = points.table.set_index(["amplitude_deg", "frequency_hz"]).sort_index()
        want = pd.Series(expected_d, index=pd.MultiIndex.from_frame(raw[["amplitude_deg", "frequency_hz"]])).sort_index()
        np.testing.assert_allclose(got["servo_damping_ratio"], want, rtol=1e-9, err_msg=name)
        assert set(points.table["sweep"]) == {"frequency", "amplitude"}
    dynamic = read_servo_results(tmp_path / "loss_factor.parquet")
    assert "dynamic stiffness |K*|" in dynamic.stiffness_definition
    np.testing.assert_allclose(dynamic.table["servo_stiffness_nm_per_deg"],
                               K_DEG * np.sqrt(1 + dynamic.table["servo_loss_factor"] ** 2), rtol=2e-3)
    # without a sweep column each point goes to the sweep with more points through it
    inferred = read_servo_results(tmp_path / "loss_angle_deg.parquet").table
    assert (inferred.query("amplitude_deg == 0.5 and frequency_hz >= 60")["sweep"] == "frequency").all()
    assert (inferred.query("amplitude_deg == 10.0 or amplitude_deg == 0.2")["sweep"] == "amplitude").all()
    assert len(inferred) == len(raw)  # a point on two sweeps is kept once, on the longer one


def test_reference_comparison_interpolates_in_log_amplitude():
    """Campaign points on a known curve c = 400 - 60 ln(a): interpolation at the reference
    amplitudes is exact inside the points, linear beyond them (flagged)."""
    heights = [0.05, 0.2, 1.0, 6.0]
    amplitudes = [0.2, 0.5, 1.0, 2.0]
    rows = [dict(inertia_kgm2=0.359, drop_mass_kg=2.0, drop_height_m=h, preload_nm=p, amplitude_deg=a,
                 frequency_hz=30 - 2 * np.log(a), stiffness_nm_per_deg=400 - 60 * np.log(a) + noise,
                 damping_ratio=1 + 0.1 * np.log(a), flags="")
            for h, a in zip(heights, amplitudes) for p, noise in ((0.0, -1.0), (500.0, 1.0))]
    rows.append(dict(rows[0], stiffness_nm_per_deg=9999.0, flags="poor_fit"))  # excluded by its flag
    results = pd.DataFrame(rows)
    reference = pd.DataFrame(dict(case=[2, 2, 2, 1], inertia_kgm2=[0.359, 0.359, 0.359, 0.1557],
                                  drop_mass_kg=[2.0, 2.0, 2.0, 1.0], amplitude_deg=[0.3, 1.5, 3.0, 1.0],
                                  frequency_hz=[30.0, 28.0, 27.0, 45.0], stiffness_nm_per_deg=[300.0] * 4,
                                  damping_ratio=[1.0] * 4))
    table, summary = compare_reference(reference, constant_map(), results)
    a = reference["amplitude_deg"].to_numpy()
    np.testing.assert_allclose(table["campaign_stiffness_nm_per_deg"][:3], 400 - 60 * np.log(a[:3]))
    np.testing.assert_allclose(table["campaign_damping_ratio"][:3], 1 + 0.1 * np.log(a[:3]))
    assert table["campaign_extrapolated"].tolist()[:3] == [False, False, True]
    assert np.isnan(table["campaign_stiffness_nm_per_deg"][3])  # no tests of case 1
    np.testing.assert_allclose(table["map_stiffness_nm_per_deg"], K_DEG * (1 + MAP_ERROR))
    np.testing.assert_allclose(table["map_stiffness_deviation_pct"], 100 * (K_DEG * (1 + MAP_ERROR) / 300 - 1))
    assert summary["map"]["n_points"] == 4 and summary["n_rows"] == 4


# ---- bad input ------------------------------------------------------------------------------------
def _one_line_error(err: str) -> str:
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("droptower: error: ") and "Traceback" not in err, err
    return lines[0]


def test_results_file_missing_columns(tmp_path, capsys):
    map_file = tmp_path / "map.json"
    constant_map().to_json(map_file)
    bad = tmp_path / "servo.csv"
    pd.DataFrame({"amplitude_deg": [1.0], "frequency_hz": [10.0], "loss_factor": [0.1]}).to_csv(bad, index=False)
    out = tmp_path / "out"
    assert main(["validate", "--map", str(map_file), "--servo-results", str(bad), "--out", str(out)]) == 2
    line = _one_line_error(capsys.readouterr().err)
    assert str(bad) in line and "lack a stiffness column (storage_stiffness_nm_per_deg or" in line
    assert not out.exists()
    pd.DataFrame({"twist": [1.0], "frequency_hz": [10.0]}).to_csv(bad, index=False)
    assert main(["validate", "--map", str(map_file), "--servo-results", str(bad)]) == 2
    line = _one_line_error(capsys.readouterr().err)
    assert "lack amplitude_deg; a stiffness column" in line and "a damping column" in line
    pd.DataFrame({"amplitude_deg": [1.0], "frequency_hz": [10.0], "loss_factor": [0.1],
                  "storage_stiffness_nm_per_deg": [200.0], "sweep": ["diagonal"]}).to_csv(bad, index=False)
    assert main(["validate", "--map", str(map_file), "--servo-results", str(bad)]) == 2
    assert "'diagonal' is neither 'frequency' nor 'amplitude'" in _one_line_error(capsys.readouterr().err)
    pd.DataFrame({"amplitude_deg": [1.0], "frequency_hz": [-10.0], "loss_factor": [0.1],
                  "storage_stiffness_nm_per_deg": [200.0]}).to_csv(bad, index=False)
    assert main(["validate", "--map", str(map_file), "--servo-results", str(bad)]) == 2
    assert "column frequency_hz: row 1 is not a positive number" in _one_line_error(capsys.readouterr().err)


def test_translational_servo_results_are_refused_with_the_reason(tmp_path, capsys):
    """The map is the torsional drop tower's: a displacement test's results (as droptower servo
    writes them for a translational coupling) and a translational coupling are refused, naming why."""
    map_file = tmp_path / "map.json"
    constant_map().to_json(map_file)
    bushing = tmp_path / "bushing.csv"
    pd.DataFrame({"amplitude_mm": [0.1], "frequency_hz": [10.0], "loss_factor": [0.1],
                  "storage_stiffness_n_per_m": [1e6]}).to_csv(bushing, index=False)
    assert main(["validate", "--map", str(map_file), "--servo-results", str(bushing)]) == 2
    line = _one_line_error(capsys.readouterr().err)
    assert str(bushing) in line and "translational servo results (amplitude_mm, storage_stiffness_n_per_m)" in line
    assert "torsional drop tower" in line
    assert main(["validate", "--map", str(map_file), "--coupling", "seed002_bushing", "--quick"]) == 2
    assert "seed002_bushing is a translational coupling" in _one_line_error(capsys.readouterr().err)


def test_bad_map_and_reference(tmp_path, capsys):
    assert main(["validate", "--map", str(tmp_path / "none.json")]) == 2
    assert "none.json: no such file" in _one_line_error(capsys.readouterr().err)
    map_file = tmp_path / "map.json"
    constant_map().to_json(map_file)
    reference = tmp_path / "table4.csv"
    pd.DataFrame({"amplitude_deg": [1.0], "frequency_hz": [30.0]}).to_csv(reference, index=False)
    assert main(["validate", "--map", str(map_file), "--reference", str(reference)]) == 2
    assert "reference map lacks column(s) inertia_kgm2, stiffness_nm_per_deg, damping_ratio" in \
        _one_line_error(capsys.readouterr().err)
    assert main(["validate", "--map", str(map_file), "--results", str(tmp_path)]) == 2
    assert "--results needs --reference" in _one_line_error(capsys.readouterr().err)
