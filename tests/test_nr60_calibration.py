"""The shipped reference coupling ``rapp2022_nr60`` and its calibration.

The calibration (analysis/calibrate_nr60.py) stores every candidate's figures in
analysis/results/nr60_candidates.csv and writes the best as the preset; the full study's
figures are checked in tests/test_study.py. Here: the shipped preset is the stored best
candidate, it is rubber-like (items 1 and 2 of the issue), its drop-tower decays agree with the
servo bench at their own points (the map-free part of item 4) and the preload does not change it.
"""
from __future__ import annotations

import importlib.util
import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import droptower as dt
from droptower.extract import Settings, extract_file
from droptower.rig import load_rig, simulate
from droptower.servo.steady import rubber_figures

ROOT = Path(__file__).resolve().parents[1]
CANDIDATES = ROOT / "analysis" / "results" / "nr60_candidates.csv"


def _calibration_module():
    spec = importlib.util.spec_from_file_location("calibrate_nr60", ROOT / "analysis" / "calibrate_nr60.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules["calibrate_nr60"] = module  # its dataclasses look their module up
    sys.path.insert(0, str(ROOT / "analysis"))  # it takes real_time_factor from run_study
    try:
        spec.loader.exec_module(module)
    finally:
        sys.path.remove(str(ROOT / "analysis"))
    return module


@pytest.fixture(scope="module")
def calibration():
    return _calibration_module()


def test_shipped_preset_is_the_stored_best_candidate(calibration):
    table = pd.read_csv(CANDIDATES)
    best = table.iloc[0]
    eligible = table[table["eligible"]]
    fewest = eligible[eligible["targets_missed"] == eligible["targets_missed"].min()]
    assert best["eligible"] and best["target_excess"] == fewest["target_excess"].min()
    values = {name: best[f"param_{name}"] for name in calibration.NAMES}
    matrix = best["candidate"] != "joint_without_matrix"
    shipped = dt.load_coupling("rapp2022_nr60")
    rebuilt = calibration.build(values, matrix)
    np.testing.assert_allclose(shipped.params, rebuilt.params, rtol=1e-9)


def test_the_preset_is_rubber_like():
    """Loss factor at 1 Hz >= 0.7x that at 30 Hz, K' rising >= 3 % per decade and a third
    harmonic <= 5 % of the fundamental (1.5 deg, 30 Hz): elliptic loops, a weak frequency
    dependence as filled rubber's."""
    figures = rubber_figures(dt.load_coupling("rapp2022_nr60"))
    assert figures["loss_factor_ratio"] >= 0.7
    assert figures["storage_rise_pct_per_decade"] >= 3.0  # K' rises a few % per decade (1-30 Hz)
    assert figures["third_harmonic_pct"] <= 5.0
    assert 0.1 < figures["loss_factor"] < 0.35  # Table 4's d of 0.5-2 is eta 0.1-0.25 (docs/theory.md#damping-measures)


def test_decays_against_the_bench_at_their_own_points(calibration):
    """The fast loop's 30 decays (3 cases x Table 2's heights) against the steady state at each
    decay's amplitude and frequency: the stiffness within 3 % RMS. The damping ratio the
    drop tower reads is higher than the bench's at every point (docs/theory.md#first-cycle): the
    filler network's friction loss grows with the amplitude, which a first cycle spanning
    amplitudes about a factor 2 apart turns into a larger decay rate than the steady loop at the
    window's middle amplitude, and the matrix branch's relaxation slower than the oscillation
    adds a creep mode that the fit reads as decay (d = (e^(4 pi r) - 1)/2 doubles the difference
    in r): measured 53 % RMS on the shipped preset (52.7 % through the pipeline,
    analysis/results/nr60_candidates.csv). The bound was 50 % for the preset before the filler
    network re-formed only while held: its loss factor at 1 Hz then had a share from the
    network's 5 s relaxation (an artifact: docs/theory.md#filler-network), and the recalibrated
    preset holds eta(1 Hz) / eta(30 Hz) >= 0.7 with more friction instead, the loss that grows
    with the amplitude and so this bias (the candidates that keep it below 50 % miss the loss
    ratio or Table 4's damping: analysis/README.md)."""
    coupling = dt.load_coupling("rapp2022_nr60")
    points = calibration.predict(coupling)
    servo = calibration.servo_at(coupling, points)
    dc = points["stiffness_nm_per_deg"] / servo["servo_stiffness_nm_per_deg"] - 1
    dd = points["damping_ratio"] / servo["servo_damping_ratio"] - 1
    assert math.sqrt(np.mean(dc ** 2)) <= 0.03
    assert np.all(dd > 0)
    assert math.sqrt(np.mean(dd ** 2)) <= 0.55


def test_stiffness_and_damping_do_not_depend_on_the_preload(tmp_path):
    """Rapp et al. 2022, Fig. 11: no influence of the preload on the coupling's behaviour. The filler
    network's centre follows the held twist and its structure recovers from the conditioning
    during the hold, the matrix branch relaxes, so the extracted values agree within 1 %."""
    rig = load_rig("rapp2022")
    coupling = dt.load_coupling("rapp2022_nr60")
    tests = pd.DataFrame([dict(inertia_kgm2=0.359, drop_mass_kg=2.0, drop_height_m=h, preload_nm=p, repeat=0, seed=1)
                          for h in (0.2, 3.5) for p in (0.0, 500.0, 1000.0)])
    rows = []
    for i, result in enumerate(simulate(rig, coupling, tests, duration_s=0.12)):
        _, extracted = extract_file(result.write_log(tmp_path / f"t{i}.parquet"), Settings())
        rows.append((extracted.stiffness_nm_per_rad, extracted.damping_ratio))
    values = np.array(rows).reshape(2, 3, 2)  # height, preload, quantity
    for loaded in (1, 2):
        np.testing.assert_allclose(values[:, loaded, :], values[:, 0, :], rtol=0.01)


@pytest.mark.slow
def test_calibration_is_reproducible(calibration):
    """Two fits from the same start give the same values to the last bit (fixed start, fixed
    finite-difference steps, no random draw), and a short fit leaves the shipped preset alone."""
    table = pd.read_csv(calibration.table4_path())
    start = {p[0]: p[3] for p in calibration.PARAMETERS}
    weights = calibration.Weights(servo_stiffness=None, servo_damping=None)
    preset = (ROOT / "rig_configs" / "couplings" / "rapp2022_nr60.toml").read_text()
    first, _ = calibration.fit(start, weights, table, None, 2)
    second, _ = calibration.fit(start, weights, table, None, 2)
    assert first == second and first != start
    assert (ROOT / "rig_configs" / "couplings" / "rapp2022_nr60.toml").read_text() == preset
