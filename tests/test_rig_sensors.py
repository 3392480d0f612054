"""Sensors of the virtual rig and the log they write (read back like any real log)."""
import math

import numpy as np
import pytest

from droptower.io.droptower_log import read_log
from droptower.rig.config import Resonance, load_rig
from droptower.rig.sensors import force_pulses, resonance, sample

FS = 38400.0


def test_force_pulse_carries_exactly_the_impulse():
    t = -0.005 + np.arange(4000) / FS
    for t_c, duration in ((1.3e-5, 3e-4), (0.0123, 3e-4), (0.02, 1e-5)):  # the last is shorter than a sample
        f = force_pulses(t, np.array([t_c]), np.array([10.87]), duration)
        assert f.sum() / FS == pytest.approx(10.87, rel=1e-12)
        nonzero = t[f > 0]
        assert nonzero.min() >= t_c - duration / 2 - 1 / FS and nonzero.max() <= t_c + duration / 2 + 1 / FS
    two = force_pulses(t, np.array([0.0, 0.03]), np.array([5.0, 1.0]), 3e-4)
    assert two[t < 0.015].sum() / FS == pytest.approx(5.0) and two[t > 0.015].sum() / FS == pytest.approx(1.0)


def test_resonance_rings_at_its_frequency_and_keeps_the_static_torque():
    res = Resonance(frequency_hz=650.0, damping_ratio=0.02, strength=1.0)
    step = np.r_[np.zeros(100), np.full(4000, 100.0)]
    y = resonance(step, FS, res)
    assert y[-1] == pytest.approx(100.0, rel=1e-3)          # unit gain at rest
    assert np.max(y) == pytest.approx(100 * (1 + math.exp(-math.pi * 0.02 / math.sqrt(1 - 0.02**2))), rel=0.01)
    ring = y[100:] - 100.0
    crossings = np.flatnonzero(np.diff(np.sign(ring)) != 0)
    f = 0.5 * FS / np.mean(np.diff(crossings[:20]))
    assert f == pytest.approx(650.0 * math.sqrt(1 - 0.02**2), rel=0.01)
    const = resonance(np.full(500, 1000.0), FS, res)       # starts at rest at the preload
    np.testing.assert_allclose(const, 1000.0, rtol=1e-9)
    assert np.array_equal(resonance(step, FS, Resonance(frequency_hz=650.0, damping_ratio=0.02, strength=0.0)), step)


def test_sample_is_seeded_and_converts_like_the_rig():
    sensors = load_rig("rapp2022").sensors
    t = -0.005 + np.arange(2000) / FS
    twist = 0.01 + 0.02 * np.sin(2 * np.pi * 30 * np.clip(t, 0, None))
    torque = 14000 * twist
    a = sample(t, twist, torque, np.array([0.0]), np.array([10.0]), sensors, seed=3)
    b = sample(t, twist, torque, np.array([0.0]), np.array([10.0]), sensors, seed=3)
    c = sample(t, twist, torque, np.array([0.0]), np.array([10.0]), sensors, seed=4)
    for name in a.columns():
        np.testing.assert_array_equal(a.columns()[name], b.columns()[name])
        assert not np.array_equal(a.columns()[name], c.columns()[name])
    np.testing.assert_allclose(a.laser_distance_m / sensors.laser.radius_m, a.angle_rad, rtol=1e-12)
    assert np.std(a.laser_distance_m - sensors.laser.radius_m * twist) == pytest.approx(sensors.laser.noise_m, rel=0.1)
    assert np.std((a.torque_nm - torque)[:150]) == pytest.approx(sensors.torque.noise_nm, rel=0.2)


def test_written_log_reads_back_with_metadata(tmp_path):
    from droptower.rheology.loader import parse_coupling
    from droptower.rig.simulate import DropTest, simulate

    rig = load_rig("rapp2022")
    coupling = parse_coupling({"name": "lin", "element": [{"kind": "spring", "stiffness": 14000.0},
                                                          {"kind": "dashpot", "damping": 15.5}]})
    result = simulate(rig, coupling, [DropTest(0.359, 2.0, 0.7, 500.0, 2, 11)], duration_s=0.01)[0]
    for suffix in (".csv", ".parquet"):
        record = read_log(result.write_log(tmp_path / f"test{suffix}"))
        assert record.names() == ["time_s", "angle_rad", "torque_nm", "impact_force_n", "laser_distance_m"]
        meta = record.metadata
        for key, value in {"rig": "rapp2022", "coupling": "lin", "inertia_kgm2": 0.359, "drop_mass_kg": 2.0,
                           "drop_height_m": 0.7, "preload_nm": 500.0, "repeat": 2, "seed": 11, "restitution": 0.5,
                           "sample_rate_hz": FS, "pre_trigger_s": 0.005, "lever_length_m": 0.2,
                           "laser_radius_m": 0.15}.items():
            assert meta[key] == value, key
        ch = result.channels()
        np.testing.assert_array_equal(record["torque_nm"].values, ch.torque_nm)
        force = record["impact_force_n"].values
        impulse = result.contacts[0].impulse_ns
        pulse = slice(np.searchsorted(result.time_s, -1e-3), np.searchsorted(result.time_s, 1e-3))
        assert force[pulse].sum() / FS == pytest.approx(impulse, rel=0.01)  # noise averages out over the pulse
        # the preload sits in the pre-trigger: torque at 500 N*m, angle at the twist
        assert np.median(record["torque_nm"].values[:150]) == pytest.approx(500.0, abs=1.0)
        assert np.median(record["angle_rad"].values[:150]) == pytest.approx(500.0 / 14000.0, rel=1e-3)
