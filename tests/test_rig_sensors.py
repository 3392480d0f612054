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
    # the pulse is centred on the impulse's time, also between samples; cut by the record's end, it keeps its impulse
    f = force_pulses(t, np.array([0.0123]), np.array([1.0]), 3e-4)
    assert np.sum(t * f) / np.sum(f) == pytest.approx(0.0123, abs=1e-9)
    end = force_pulses(t, np.array([t[-2]]), np.array([2.0]), 3e-4)
    assert end.sum() / FS == pytest.approx(2.0, rel=1e-12)


def test_a_long_contact_is_a_long_low_force():
    """A contact history (a steady 9.81 N for 0.1 s, as the drop mass resting on the lever) keeps
    its force; an impact in the same record stays one 0.3 ms pulse."""
    t = -0.005 + np.arange(6000) / FS
    rest = (t >= 0.05) & (t < 0.15)
    history = np.where(rest, 9.81 / FS, 0.0)
    history[np.searchsorted(t, 0.0)] = 1.2
    f = force_pulses(t, t, history, 3e-4)
    assert f.sum() / FS == pytest.approx(history.sum(), rel=1e-12)
    np.testing.assert_allclose(f[(t > 0.051) & (t < 0.149)], 9.81, rtol=1e-12)
    assert np.all(f[(t > 1.6e-4) & (t < 0.0498)] == pytest.approx(0.0, abs=1e-9))
    assert np.max(f) == pytest.approx(np.pi * 1.2 / (2 * 3e-4), rel=0.02)


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
    np.testing.assert_allclose(a.laser_distance_m / sensors.laser.radius_m, np.tan(a.angle_rad), rtol=1e-12)
    assert np.std(a.laser_distance_m - sensors.laser.radius_m * np.tan(twist)) == pytest.approx(sensors.laser.noise_m, rel=0.1)
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


def test_drop_mass_resting_on_the_lever_is_not_an_impact():
    """Case 1 (0.1557 kg m², 1 kg, 0.05 m): the drop mass bounces and comes to rest on the lever
    at ~0.06 s for the rest of the 0.25 s record (~1.9 N*s over ~14 000 steps). The force
    channel shows it as its weight, the impact stays the largest pulse, and the extractor finds
    the impact at its time, not a double impact (the rest comes after the first period)."""
    from droptower.extract.extractor import extract
    from droptower.io.signals import DropSignals
    from droptower.rheology.loader import parse_coupling
    from droptower.rig.simulate import DropTest, simulate

    rig = load_rig("rapp2022")
    coupling = parse_coupling({"name": "lin", "element": [{"kind": "spring", "stiffness": 14000.0},
                                                          {"kind": "dashpot", "damping": 15.5}]})
    r = simulate(rig, coupling, [DropTest(0.1557, 1.0, 0.05, seed=5)], duration_s=0.25)[0]
    impact, resting = r.contacts[0], max(r.contacts, key=lambda c: c.steps)
    assert resting.steps * rig.dt_s > 0.1 and resting.impulse_ns > impact.impulse_ns  # the condition is there
    duration = rig.sensors.impact_force.contact_duration_s
    ideal = force_pulses(r.time_s, r.time_s, r.contact_impulse_ns, duration)
    assert ideal.sum() / FS == pytest.approx(sum(c.impulse_ns for c in r.contacts), rel=1e-12)
    assert abs(r.time_s[np.argmax(ideal)] - impact.start_s) <= 1 / FS
    on = r.time_s > resting.start_s + 0.01
    assert np.max(ideal[on]) < 3 * 9.81 and np.mean(ideal[on]) == pytest.approx(9.81, rel=0.05)
    assert not r.warnings

    ch = r.channels()
    assert abs(ch.time_s[np.argmax(ch.impact_force_n)] - impact.start_s) <= 1 / FS
    result = extract(DropSignals(time_s=ch.time_s, angle_rad=ch.angle_rad, torque_nm=ch.torque_nm,
                                 impact_force_n=ch.impact_force_n, metadata=r.metadata()))
    assert impact.start_s - duration / 2 - 1 / FS <= result.impact_time_s <= impact.start_s
    assert r.period_s < r.contacts[1].start_s - impact.start_s
    assert not result.double_impact and not r.double_impact
    assert result.impact_impulse_ns == pytest.approx(impact.impulse_ns, rel=0.02)
    assert result.stiffness_nm_per_rad == pytest.approx(14000.0, rel=0.01)  # Kelvin-Voigt: J (omega² + delta²) = K


def test_laser_reads_the_vertical_displacement_at_its_radius_and_back():
    """The laser looks along a fixed vertical line at the spot radius R, as the drop mass
    falls along one at L: it reads R tan(phi) (the impact geometry's L tan(phi)), not the arc
    R phi, and the reader inverts exactly that, so writing and reading agree at any angle."""
    from droptower.io.mapping import laser_angle, laser_distance

    phi = np.radians(np.array([-10.0, -3.0, 0.0, 0.5, 3.0, 10.0]))
    np.testing.assert_allclose(laser_distance(phi, 0.15), 0.15 * np.tan(phi), rtol=1e-15)
    np.testing.assert_allclose(laser_angle(laser_distance(phi, 0.15), 0.15), phi, rtol=1e-14, atol=1e-18)
    # at 3 deg the arc would be 0.09 % short: the two geometries are told apart
    assert laser_distance(np.radians(3.0), 1.0) / np.radians(3.0) - 1 == pytest.approx(9.1e-4, rel=0.02)
