"""The reference coupling ``rapp2022_nr60`` at quasi-static rates and under a held preload
(docs/theory.md#filler-network): its filler network re-forms only while it is held, so a slow
sine sees the same rate-independent network as a 1 Hz one, and a preload set by a ramp and a
hold leaves the network of an unloaded test. Each figure is measured here on the servo bench or
its exact steady state; the un-gated network (re-forming at any rate) is the control that shows
what each test would catch."""
from __future__ import annotations

import json
import tomllib
from pathlib import Path

import numpy as np
import pytest

from droptower.configs import resolve
from droptower.rheology import load_coupling, parse_coupling
from droptower.servo import run_grid
from droptower.servo.steady import steady_state

ROOT = Path(__file__).resolve().parents[1]
FREQUENCIES_HZ = [0.01, 0.03, 0.1, 1.0]
AMPLITUDES_DEG = [0.5, 1.5]


def _ungated():
    """The preset with a network that re-forms at any rate (the element before the rest factor)."""
    data = tomllib.loads(resolve("rapp2022_nr60", "couplings").read_text())
    for el in data["element"]:
        if el["kind"] == "filler_network":
            el["rest_rate"] = 1e9
    return parse_coupling(data)


def _low_rate_figures(coupling) -> tuple[np.ndarray, np.ndarray]:
    """K' (N*m/rad) and the loss factor, (amplitude, frequency), exact steady state at 4096 steps a cycle."""
    k, eta = [], []
    for a in AMPLITUDES_DEG:
        ss = steady_state(coupling, np.radians([a] * len(FREQUENCIES_HZ)), FREQUENCIES_HZ, simulation_rate_hz=1.0)
        k.append(ss.storage_stiffness_nm_per_rad)
        eta.append(ss.loss_factor)
    return np.array(k), np.array(eta)


def test_loss_factor_and_storage_stiffness_at_quasi_static_rates():
    """0.01, 0.03, 0.1 and 1 Hz at 0.5 and 1.5 deg: the loss factor within 1.5x of its 1 Hz
    value (filled rubber's friction loss is rate-independent; measured 0.93-1.01x) and K'
    rising with the frequency (the matrix branch; no dip at low rates). The un-gated network
    relaxes under the slow sines like a Maxwell element with the centre's 5 s: a loss peak
    (2.7-4x the 1 Hz value at 0.01 Hz) and K' 29-48 % below its 1 Hz value."""
    k, eta = _low_rate_figures(load_coupling("rapp2022_nr60"))
    ratio = eta / eta[:, -1:]
    assert np.all((ratio >= 1 / 1.5) & (ratio <= 1.5)), ratio
    assert np.all(np.diff(k, axis=1) > 0), k
    k_free, eta_free = _low_rate_figures(_ungated())
    assert np.all(eta_free[:, 0] > 1.5 * eta_free[:, -1]) and np.all(k_free[:, 0] < 0.8 * k_free[:, -1])


@pytest.mark.parametrize("frequency_hz", [1.0, 10.0])
def test_servo_bench_under_a_held_preload_agrees_with_the_unloaded_test(frequency_hz):
    """Rapp et al. 2022, Fig. 11: no influence of the preload. On the bench the preload is set as
    the drop tower sets it, a quasi-static ramp and a hold (60 s): K' and the loss factor at 500
    and 1000 N*m within 1 % of the unloaded ones at 0.5 and 1.5 deg (the hold leaves at most
    e^-6 = 0.25 % of the ramp's breakdown unrecovered, and each test breaks the network down to
    its own amplitude's level; measured within 0.01 %). Without the hold the twist of the ramp
    about a centre that had no time to follow breaks the network down: 17-32 % softer."""
    amps = np.radians(AMPLITUDES_DEG)
    base = run_grid("rapp2022_nr60", amps, [frequency_hz])
    for preload in (500.0, 1000.0):
        held = run_grid("rapp2022_nr60", amps, [frequency_hz], preload_nm=preload)
        np.testing.assert_allclose(held["mean_torque_nm"], preload, rtol=1e-3)
        for column in ("storage_stiffness_nm_per_rad", "loss_factor"):
            np.testing.assert_allclose(held[column], base[column], rtol=0.01, err_msg=f"{column} at {preload} N*m")
    rushed = run_grid("rapp2022_nr60", amps, [frequency_hz], preload_nm=500.0, preload_hold_s=0.0)
    assert np.all(rushed["storage_stiffness_nm_per_rad"] < 0.95 * base["storage_stiffness_nm_per_rad"])


def test_stored_study_has_no_preload_effect():
    """The stored full study's Table-4 comparison per preload (150 drop tests each, their own
    sensor noise): the RMS deviations at 500 and 1000 N*m within 0.25 percentage points of the
    unloaded ones, as Fig. 11 of Rapp et al. 2022 shows no influence of the preload."""
    summary = json.loads((ROOT / "analysis" / "results" / "summary.json").read_text())
    by_preload = summary["table4_by_preload_nm"]
    assert set(by_preload) == {"0", "500", "1000"}
    for preload in ("500", "1000"):
        for key in ("stiffness_rms_deviation_pct", "damping_rms_deviation_pct"):
            assert abs(by_preload[preload][key] - by_preload["0"][key]) <= 0.25, (preload, key)
