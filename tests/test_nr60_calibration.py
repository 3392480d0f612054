"""The shipped reference coupling ``rapp2022_nr60`` and its calibration.

The calibration (analysis/calibrate_nr60.py) stores every candidate's figures in
analysis/results/nr60_candidates.csv and writes the best as the preset; the full study's
figures are checked in tests/test_study.py. Here: the shipped preset is the stored best
candidate, it is rubber-like (items 1 and 2 of the issue), its drop-tower decays agree with the
servo bench at their own points in stiffness and read the damping the first cycle's two mechanisms
predict (the map-free part of item 4), no calibration on the stored frontier meets the bias bound
with the other targets, and the preload does not change it.
"""
from __future__ import annotations

import importlib.util
import math
import sys
import tomllib
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import droptower as dt
from droptower.compare.first_cycle import loop_span_damping_ratio
from droptower.configs import resolve
from droptower.extract import Settings, extract_file
from droptower.rheology import parse_coupling
from droptower.rig import load_rig, simulate
from droptower.servo.steady import rubber_figures

ROOT = Path(__file__).resolve().parents[1]
CANDIDATES = ROOT / "analysis" / "results" / "nr60_candidates.csv"
FRONTIER = ROOT / "analysis" / "results" / "nr60_frontier.csv"


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


def _preset_without(kind: str):
    """The shipped preset with its elements of ``kind`` left out (one mechanism at a time)."""
    data = tomllib.loads(resolve("rapp2022_nr60", "couplings").read_text())
    data["element"] = [el for el in data["element"] if el["kind"] != kind]
    return parse_coupling(data)


def _rms(x) -> float:
    return math.sqrt(np.mean(np.square(x)))


def test_no_calibration_on_the_frontier_meets_the_bias_bound(calibration):
    """analysis/results/nr60_frontier.csv (``calibrate_nr60.py --frontier``): its first row is the
    shipped preset, and none of its variants keeps the decays' damping bias against the bench
    below 50 % RMS while meeting the loss-factor ratio (>= 0.7) and Table 4 (stiffness <= 5 %,
    damping <= 12 %): those below 50 % miss the ratio or Table 4's damping."""
    frontier = pd.read_csv(FRONTIER)
    assert frontier["variant"].iloc[0] == "preset"
    shipped = dt.load_coupling("rapp2022_nr60")
    rebuilt = calibration.build({n: frontier[f"param_{n}"].iloc[0] for n in calibration.NAMES})
    np.testing.assert_allclose(shipped.params, rebuilt.params, rtol=1e-9)
    assert not frontier["meets_all"].any()
    below = frontier[frontier["decay_vs_servo_damping_rms_pct"] <= 50.0]
    assert len(below) >= 2
    assert np.all((below["loss_factor_ratio_1hz_30hz"] < 0.7) | (below["table4_damping_rms_pct"] > 12.0)
                  | (below["table4_stiffness_rms_pct"] > 5.0))


@pytest.mark.slow
def test_decays_against_the_bench_at_their_own_points(calibration, regression):
    """The fast loop's 30 decays (3 cases x Table 2's heights) against the steady state at each
    decay's amplitude and frequency: the stiffness within 3 % RMS; the damping ratio the drop
    tower reads is higher than the bench's at every point (53 % RMS), and the two mechanisms of
    docs/theory.md#first-cycle predict by how much, each computed from the model on its own:

    - the stiffness changes over the amplitudes the first cycle spans (about a factor 2): the
      energy balance of the decay with the coupling's own steady loops over that span
      (:func:`droptower.compare.first_cycle.loop_span_damping_ratio`). The cycle loses the
      energy the bench's loop shows (within 1-4 %), but the Payne effect's stiffness rises as the
      amplitude falls, (A_0 / A_1)^2 = (E_0 / E_1) K'(A_1) / K'(A_0), so the amplitude falls faster
      than the energy: 28 % above the bench on its own;
    - the matrix branch's relaxation slower than the oscillation: a creep mode the fit reads as
      decay, measured as the reading over the bench of the preset's linear part (spring and
      matrix, no friction) dropped from the same height.

    Their product predicts the readings as well as the energy balance alone predicts those of the
    preset's spring and filler network alone, where the amplitude span is the only mechanism
    (measured 4.9 % RMS against 6.2 %), and neither mechanism alone does (19.6 % and 30 %). No
    calibration of this model keeps the bias below 50 % RMS and meets the loss-factor ratio and
    Table 4's damping (analysis/README.md: the frontier)."""
    coupling = dt.load_coupling("rapp2022_nr60")
    points = calibration.predict(coupling)
    servo = calibration.servo_at(coupling, points)
    dc = points["stiffness_nm_per_deg"] / servo["servo_stiffness_nm_per_deg"] - 1
    read, bench = points["damping_ratio"].to_numpy(), servo["servo_damping_ratio"].to_numpy()
    assert _rms(dc) <= 0.03
    assert np.all(read > bench)

    span = loop_span_damping_ratio(coupling, np.radians(points["initial_amplitude_deg"]), points["frequency_hz"])
    linear = _preset_without("filler_network")
    linear_points = calibration.predict(linear)  # the same lever cases and impacts
    creep = linear_points["damping_ratio"].to_numpy() / calibration.servo_at(linear, linear_points)[
        "servo_damping_ratio"].to_numpy()
    predicted = span * creep
    network = _preset_without("power_law")
    network_points = calibration.predict(network)
    alone = network_points["damping_ratio"] / loop_span_damping_ratio(
        network, np.radians(network_points["initial_amplitude_deg"]), network_points["frequency_hz"]) - 1
    assert np.all(creep > 1) and np.all(predicted > bench)  # both mechanisms raise the reading
    assert _rms(read / predicted - 1) <= _rms(alone)
    assert min(_rms(read / span - 1), _rms(read / (bench * creep) - 1)) > _rms(alone)  # neither alone
    # the figures docs/theory.md#first-cycle states (analysis/readme_figures.py renders them from
    # tests/data/regression/): deterministic simulations, reproducible to round-off
    network_bench = calibration.servo_at(network, network_points)["servo_damping_ratio"].to_numpy()
    for key, value in (("read_over_bench_rms", _rms(read / bench - 1)), ("span_over_bench_rms", _rms(span / bench - 1)),
                       ("network_over_bench_rms", _rms(network_points["damping_ratio"].to_numpy() / network_bench - 1)),
                       ("network_span_error_rms", _rms(alone)), ("creep_min", creep.min()), ("creep_max", creep.max()),
                       ("predicted_error_rms", _rms(read / predicted - 1)),
                       ("predicted_error_min", np.min(read / predicted - 1)),
                       ("predicted_error_max", np.max(read / predicted - 1)),
                       ("span_alone_error_rms", _rms(read / span - 1)),
                       ("creep_alone_error_rms", _rms(read / (bench * creep) - 1))):
        regression.check(key, value, rel=1e-6)


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
