"""Imposed angle histories of the servo bench: shapes, markers, continuity, reproducibility."""
import math

import numpy as np
import pytest

from droptower.errors import DroptowerError
from droptower.servo import histories as H

FS = 2048.0


def _max_rate(h: H.History) -> float:
    return float(np.max(np.abs(np.diff(h.angle_rad)))) * h.sample_rate_hz


def _covers(h: H.History) -> None:
    """Segments tile the history without gaps, and the history starts at rest at 0."""
    segs = h.segments
    assert segs[0].start_s == 0.0
    for a, b in zip(segs, segs[1:]):
        assert b.start_s == pytest.approx(a.stop_s, abs=1e-12)
    assert h.time_s[-1] == pytest.approx(segs[-1].stop_s, abs=1.0 / h.sample_rate_hz)
    assert h.angle_rad[0] == 0.0
    np.testing.assert_allclose(np.diff(h.time_s), 1.0 / h.sample_rate_hz, rtol=1e-9)


def test_sine_segments_offset_and_whole_cycles():
    f, a, off = 10.0, 0.02, 0.05
    h = H.sine(f, a, FS, offset_rad=off, run_in_cycles=4, cycles=3, ramp_cycles=2)
    _covers(h)
    assert [s.label for s in h.segments] == ["offset ramp", "run-in", "evaluation", "tail"]
    ev = h.evaluation_segments[0]
    assert ev.cycles == 3 and ev.duration_s == pytest.approx(0.3)
    assert ev.start_s == pytest.approx((2 + 4) / f)
    # the evaluation window is the exact sine about the offset
    idx = h.indices(ev)
    t = h.time_s[idx] - ev.start_s
    np.testing.assert_allclose(h.angle_rad[idx], off + a * np.sin(2 * np.pi * f * t), atol=1e-15)
    # no jumps: the offset ramp (raised cosine over 2 periods) moves at most off * pi f / 4, the
    # growing sine at most a f (2 pi + pi / 4)
    assert _max_rate(h) <= max(off * np.pi * f / 4, a * f * (2 * np.pi + np.pi / 4)) * 1.001
    assert h.angle_rad[h.indices(h.segments[0])][-1] == pytest.approx(off, rel=1e-3)


def test_sine_is_linear_in_offset_and_amplitude():
    # the bench builds its batch rows from two unit histories: this must be exact
    h = H.sine(7.0, 0.013, FS, offset_rad=-0.04)
    u = H.sine(7.0, 1.0, FS).angle_rad
    r = H.sine(7.0, 0.0, FS, offset_rad=1.0).angle_rad
    np.testing.assert_allclose(h.angle_rad, -0.04 * r + 0.013 * u, atol=1e-15)


def test_frequency_sweep_steps_are_continuous_and_marked():
    freqs = [2.0, 5.0, 12.5]
    h = H.frequency_sweep(freqs, 0.01, FS, run_in_cycles=3, cycles=2)
    _covers(h)
    evs = h.evaluation_segments
    assert [s.frequency_hz for s in evs] == freqs
    assert all(s.cycles == 2 for s in evs)
    # the angle never jumps: the largest step is the sine's own at the top frequency
    assert _max_rate(h) <= 2 * np.pi * 12.5 * 0.01 * 1.001
    for s in evs:
        assert np.max(np.abs(h.angle_rad[h.indices(s)])) == pytest.approx(0.01, rel=2e-3)


def test_amplitude_sweep_levels():
    amps = [0.005, 0.02, 0.01]
    h = H.amplitude_sweep(amps, 10.0, FS, run_in_cycles=3, cycles=2)
    _covers(h)
    evs = h.evaluation_segments
    assert [s.amplitude_rad for s in evs] == amps
    for s, a in zip(evs, amps):
        assert np.max(np.abs(h.angle_rad[h.indices(s)])) == pytest.approx(a, rel=2e-3)
    assert _max_rate(h) <= 2 * np.pi * 10.0 * 0.02 * 1.05


def test_dual_frequency_common_period_and_waveform():
    assert H.common_frequency([5.0, 7.5]) == 2.5  # the elastoslide paper's 1/rev and lag/rev tests
    assert H.common_frequency([3.0, 4.5, 6.0]) == 1.5
    h = H.dual_frequency((5.0, 7.5), (0.01, 0.02), FS, run_in_cycles=2, cycles=3)
    _covers(h)
    ev = h.evaluation_segments[0]
    assert ev.frequency_hz == 2.5 and ev.cycles == 3
    assert ev.components_hz == (5.0, 7.5) and ev.component_amplitudes_rad == (0.01, 0.02)
    idx = h.indices(ev)
    t = h.time_s[idx] - ev.start_s
    expect = 0.01 * np.sin(2 * np.pi * 5.0 * t) + 0.02 * np.sin(2 * np.pi * 7.5 * t)
    np.testing.assert_allclose(h.angle_rad[idx], expect, atol=1e-15)


def test_dual_frequency_without_common_period_is_an_error():
    with pytest.raises(DroptowerError, match="common period"):
        H.common_frequency([1.0, math.pi])


def test_steps_hold_their_levels():
    levels = [0.01, -0.02, 0.0]
    h = H.steps(levels, FS, hold_s=0.2, rise_s=0.01)
    _covers(h)
    holds = [s for s in h.segments if s.label == "hold"]
    for s, level in zip(holds, levels):
        np.testing.assert_allclose(h.angle_rad[h.indices(s)], level, atol=1e-15)
    # a raised-cosine rise of 0.03 rad over 10 ms moves at most pi/2 * 0.03 / 0.01 rad/s
    assert _max_rate(h) <= np.pi / 2 * 0.03 / 0.01 * 1.001


def test_ramps_move_at_constant_rate():
    h = H.ramps(0.05, 0.1, FS, cycles=2)
    _covers(h)
    rates = np.abs(np.diff(h.angle_rad)) * FS
    np.testing.assert_allclose(rates[rates > 1e-9].max(), 0.1, rtol=1e-9)
    assert h.angle_rad.max() == pytest.approx(0.05) and h.angle_rad.min() == pytest.approx(-0.05)
    assert h.time_s[-1] == pytest.approx(4 * 0.05 * 2 / 0.1, abs=1 / FS)  # two cycles of 4 peaks each
    assert h.angle_rad[-1] == pytest.approx(0.0, abs=1e-12)


def test_random_profile_seeded_band_and_rms():
    band, rms = (5.0, 40.0), 0.01
    a = H.random_profile(rms, band, 8.0, FS, seed=3)
    b = H.random_profile(rms, band, 8.0, FS, seed=3)
    c = H.random_profile(rms, band, 8.0, FS, seed=4)
    np.testing.assert_array_equal(a.angle_rad, b.angle_rad)
    assert not np.allclose(a.angle_rad, c.angle_rad)
    assert np.sqrt(np.mean(a.angle_rad ** 2)) == pytest.approx(rms, rel=1e-9)
    assert a.angle_rad[0] == 0.0 and abs(a.angle_rad[-1]) < 1e-6 * rms
    # power outside an octave around the band is small (4th-order Butterworth, run twice)
    spec = np.abs(np.fft.rfft(a.angle_rad)) ** 2
    freq = np.fft.rfftfreq(a.angle_rad.size, 1.0 / FS)
    outside = spec[(freq < band[0] / 2) | (freq > band[1] * 2)].sum() / spec.sum()
    assert outside < 0.01


def test_random_profile_with_offset_starts_from_rest():
    h = H.random_profile(0.005, (0.0, 20.0), 4.0, FS, seed=1, offset_rad=0.03)
    _covers(h)
    seg = [s for s in h.segments if s.label == "random"][0]
    assert np.mean(h.angle_rad[h.indices(seg)]) == pytest.approx(0.03, abs=0.003)


@pytest.mark.parametrize("call", [
    lambda: H.sine(0.0, 0.01, FS),
    lambda: H.sine(10.0, 0.01, FS, cycles=0),
    lambda: H.sine(10.0, 0.01, FS, run_in_cycles=1, ramp_cycles=2),
    lambda: H.frequency_sweep([], 0.01, FS),
    lambda: H.random_profile(0.01, (50.0, 2000.0), 1.0, FS),
    lambda: H.steps([0.1], FS, hold_s=0.0),
])
def test_bad_history_parameters_are_one_line_errors(call):
    with pytest.raises(DroptowerError) as err:
        call()
    assert "\n" not in str(err.value)
