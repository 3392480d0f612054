"""What a notebook user hits: a NaN sample refused by name and index at every Python entry point
(no sample silently dropped), a simulated drop's own objects accepted by ``extract``, a
mistyped path named as the cause."""
from __future__ import annotations

import numpy as np
import pytest

from droptower import sdof
from droptower.errors import DroptowerError
from droptower.extract import Settings, Window, extract
from droptower.identify import make_segment
from droptower.identify.droplogs import ReadSettings, read_decays
from droptower.rheology.loader import parse_coupling
from droptower.servo import evaluate_cycles


def _record(n=2048):
    t = np.arange(n) / 1000.0
    angle = 0.01 * np.sin(2 * np.pi * 5.0 * t)
    return t, angle, 1000.0 * angle


@pytest.mark.parametrize("which, name", [(0, "time_s"), (1, "angle_rad"), (2, "torque_nm")])
@pytest.mark.parametrize("bad, word", [(np.nan, "NaN"), (np.inf, "infinite"), (-np.inf, "infinite")])
def test_make_segment_refuses_a_non_finite_sample(which, name, bad, word):
    arrays = list(_record())
    arrays[which] = arrays[which].copy()
    arrays[which][1234] = bad
    with pytest.raises(DroptowerError, match=rf"{name}: sample 1234 is {word} \(1 of 2048 non-finite"):
        make_segment(*arrays)


def test_a_finite_segment_keeps_every_sample():
    t, angle, torque = _record()
    seg = make_segment(t, angle, torque)
    compared = np.isfinite(seg.torque_nm) if hasattr(seg, "torque_nm") else None
    assert compared is None or compared.sum() == t.size


def test_servo_history_refuses_nan_by_name():
    t, angle, torque = _record()
    torque[7] = np.nan
    with pytest.raises(DroptowerError, match="torque_nm: sample 7 is NaN"):
        evaluate_cycles(t, angle, torque, 5.0, 0.0, 2)


def test_coupling_history_refuses_nan_by_name():
    coupling = parse_coupling({"name": "k", "element": [{"kind": "spring", "stiffness": 1e4}]})
    with pytest.raises(DroptowerError, match="angle_rad: sample 3 is NaN"):
        coupling.simulate(np.array([0.0, 0.1, 0.2, np.nan]), 1e-3)


@pytest.mark.parametrize("kwargs", [{"sample_rate_hz": np.nan}, {"sample_rate_hz": np.inf}, {"pre_trigger_s": -1.0},
                                    {"min_drop_spacing_s": np.nan}, {"window": "first"}])
def test_extraction_settings_refuse_non_finite(kwargs):
    with pytest.raises(DroptowerError, match="Settings"):
        Settings(**kwargs)


@pytest.mark.parametrize("text", ["inf", "nan", "-1", "0", "inf-cycles"])
def test_window_refuses_non_finite(text):
    with pytest.raises(DroptowerError, match="window"):
        Window.parse(text)


@pytest.fixture(scope="module")
def drop():
    from droptower.rig.config import load_rig
    from droptower.rig.simulate import DropTest, simulate

    inertia, stiffness, r = 0.359, 14_000.0, float(sdof.decay_ratio(1.5))
    omega = np.sqrt(stiffness / (inertia * (1 + r * r)))
    coupling = parse_coupling({"name": "kv", "element": [
        {"kind": "spring", "stiffness": stiffness}, {"kind": "dashpot", "damping": 2 * inertia * r * omega}]})
    return simulate(load_rig("rapp2022"), coupling, [DropTest(inertia, 2.0, 0.4, 0.0, seed=1)], duration_s=0.15)[0]


def test_extract_takes_a_simulated_drop(drop):
    from_signals = extract(drop.signals())
    assert from_signals.damping_ratio == pytest.approx(1.5, rel=0.05)
    # the rig's channels (no metadata): refused with the call that works, accepted with the inertia
    with pytest.raises(DroptowerError, match=r"DropResult.signals\(\)"):
        extract(drop.channels())
    from_channels = extract(drop.channels(), inertia_kgm2=drop.test.inertia_kgm2)
    assert from_channels.damping_ratio == pytest.approx(from_signals.damping_ratio, rel=1e-9)


@pytest.mark.parametrize("thing", [None, 3, "log.csv", {"time_s": [0, 1]}, np.zeros(5)])
def test_extract_refuses_other_types(thing):
    with pytest.raises(TypeError, match="extract expects DropSignals"):
        extract(thing)


def test_read_decays_names_a_missing_path(tmp_path):
    missing = tmp_path / "no_such_log.csv"
    with pytest.raises(DroptowerError, match=r"no_such_log\.csv: no such file"):
        read_decays([missing], ReadSettings())
    with pytest.raises(DroptowerError, match=r"no_such_log\.csv: no such file"):
        read_decays(str(missing), ReadSettings())  # one path, not its characters
