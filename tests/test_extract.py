"""The extractor (Rapp et al. 2022, eq. 13-18, docs/theory.md#decay, #extraction, #damping-measures) against closed forms,
the paper's Tables 3 and 4, and synthetic logs with known stiffness and damping."""
from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from droptower.errors import DroptowerError
from droptower import sdof
from droptower.extract.extractor import extract
from droptower.extract.synthetic import SyntheticDrop
from droptower.extract.window import Window
from droptower.io.signals import DropSignals

DEG = math.pi / 180.0


# --- formulas ----------------------------------------------------------------------------

# Rapp et al. 2022, Table 3: δ_var (1/s), ω_var (rad/s), d_ratio as printed
TABLE3 = [(33.031, 293.64, 1.5552), (18.373, 164.81, 1.5295), (16.426, 154.59, 1.4005)]


@pytest.mark.parametrize("delta, omega, d_ratio", TABLE3)
def test_table3_damping_ratio_to_four_digits(delta, omega, d_ratio):
    assert sdof.damping_ratio(delta, omega) == pytest.approx(d_ratio, rel=1e-4)


def test_table4_stiffness_from_inertia_frequency_and_damping():
    from droptower.data import read_table4

    table = read_table4()
    assert len(table) == 30
    c = sdof.stiffness_from_map(table.inertia_kgm2, table.frequency_hz, table.damping_ratio) * DEG
    np.testing.assert_allclose(c, table.stiffness_nm_per_deg, rtol=5e-4)


def test_decay_ratio_inverts_damping_ratio():
    r = np.linspace(0.0, 0.2, 21)
    np.testing.assert_allclose(sdof.decay_ratio(sdof.damping_ratio(r, 1.0)), r, atol=1e-14)


def test_stiffness_is_the_sdof_stiffness():
    # J φ'' + d φ' + c φ = 0 has roots −δ ± iω with δ = d/2J, ω = sqrt(c/J − δ²)
    J, c, d = 0.359, 14_000.0, 12.0
    roots = np.roots([J, d, c])
    delta, omega = -roots[0].real, abs(roots[0].imag)
    assert sdof.stiffness(J, omega, delta) == pytest.approx(c, rel=1e-12)


def test_reference_amplitude_is_the_envelope_mid_window():
    assert sdof.reference_amplitude(2.0, 10.0, 0.04) == pytest.approx(2.0 * math.exp(-0.2))


def test_damping_measures_numbers_of_the_theory():
    # docs/theory.md#damping-measures: r = 0.05 -> ψ 0.63, d_ratio 0.44; r = 0.10 -> both ≈ 1.25; r = 0.12 -> ψ 1.49, d_ratio 1.76.
    # docs/theory.md#damping-measures quotes ψ ≈ 2πη; the DIN definition (W_el = ½ T̂ φ̂) gives 2πη / √(1 + η²).
    for r, psi, d in [(0.05, 0.63, 0.44), (0.10, 1.25, 1.25), (0.12, 1.49, 1.76)]:
        eta = sdof.loss_factor(r, 1.0)
        assert 2 * np.pi * eta == pytest.approx(psi, abs=0.01)
        assert sdof.relative_damping(r, 1.0) == pytest.approx(2 * np.pi * eta / np.sqrt(1 + eta**2), rel=1e-12)
        assert sdof.damping_ratio(r, 1.0) == pytest.approx(d, abs=0.01)


def test_loss_factor_and_psi_are_those_of_the_kelvin_voigt_loop():
    """Drive T = cφ + dφ' with φ = φ̂ sin ωt: η = K''/K' from the first harmonic, ψ = W_D / (½T̂φ̂)
    with W_D the loop area and T̂ the torque amplitude, computed numerically (DIN 740-2
    definitions, docs/theory.md#damping-measures)."""
    J, delta, omega = 0.359, 21.0, 196.0
    c, d = sdof.stiffness(J, omega, delta), 2 * J * delta
    t = np.linspace(0.0, 2 * np.pi / omega, 20001)
    phi = 0.01 * np.sin(omega * t)
    torque = c * phi + d * 0.01 * omega * np.cos(omega * t)
    k_storage = 2 * np.trapezoid(torque * np.sin(omega * t), t) / t[-1] / 0.01
    k_loss = 2 * np.trapezoid(torque * np.cos(omega * t), t) / t[-1] / 0.01
    loop = np.trapezoid(torque, phi)
    torque_amplitude = 0.5 * (torque.max() - torque.min())
    assert sdof.loss_factor(delta, omega) == pytest.approx(k_loss / k_storage, rel=1e-6)
    assert sdof.relative_damping(delta, omega) == pytest.approx(loop / (0.5 * torque_amplitude * 0.01), rel=1e-6)
    # the servo bench's conversion back to the drop tower's d_ratio inverts the loss factor
    assert sdof.drop_tower_equivalent_damping_ratio(sdof.loss_factor(delta, omega)) == pytest.approx(
        sdof.damping_ratio(delta, omega), rel=1e-12)


# --- synthetic logs with known stiffness and damping ----------------------------------------

def check_accuracy(drop: SyntheticDrop, result) -> None:
    assert result.stiffness_nm_per_rad == pytest.approx(drop.stiffness_nm_per_rad, rel=0.01)
    assert result.damping_ratio == pytest.approx(drop.damping_ratio, rel=0.03)
    assert result.frequency_hz == pytest.approx(drop.omega / (2 * np.pi), rel=0.005)


@pytest.mark.parametrize("rate", [38_400.0, 2048.0])
@pytest.mark.parametrize("d_ratio", [1.0, 1.8])
def test_synthetic_linear_log(rate, d_ratio):
    drop = SyntheticDrop(sample_rate_hz=rate, damping_ratio=d_ratio, ringing_fraction=0.3, ringing_hz=720.0,
                         preload_nm=500.0, seed=11)
    result = extract(drop.signals())
    check_accuracy(drop, result)
    # eq. 17: the torque fit gives the same stiffness despite the ringing (paper: within 5 %)
    assert result.stiffness_torque_nm_per_rad == pytest.approx(drop.stiffness_nm_per_rad, rel=0.02)
    assert abs(result.stiffness_deviation) < 0.02
    # eq. 18: φ̂_ref is the true envelope in the middle of the window (time since the lever moved)
    moved = result.impact_time_s - (drop.pretrigger_s + drop.pulse_s / 2)
    envelope = drop.amplitude_deg * DEG * np.exp(-drop.delta * (result.window_end_s / 2 + moved))
    assert result.amplitude_ref_rad == pytest.approx(envelope, rel=0.01)
    # the first complete cycle (Rapp et al. 2022)
    assert result.window_end_s == pytest.approx(2 * np.pi / drop.omega, rel=0.01)
    # servo-comparable damping of the same linear coupling (docs/theory.md#damping-measures)
    assert result.loss_factor == pytest.approx(sdof.loss_factor(drop.delta, drop.omega), rel=0.03)
    assert result.relative_damping_psi == pytest.approx(sdof.relative_damping(drop.delta, drop.omega), rel=0.03)
    # impact: the fit's start velocity and the force impulse agree with the truth (docs/theory.md#impact)
    assert result.decay_fit_initial_rate_rad_per_s == pytest.approx(drop.impact_velocity_rad_per_s, rel=0.01)
    assert result.lever_rate_after_rad_per_s == pytest.approx(drop.impact_velocity_rad_per_s, rel=0.02)
    # offsets: sensor offset + preload, removed before fitting
    assert result.torque_offset_nm == pytest.approx(drop.torque_offset_nm + drop.preload_nm, abs=1.0)
    assert result.angle_offset_rad == pytest.approx(
        drop.angle_offset_deg * DEG + drop.preload_nm / drop.stiffness_nm_per_rad, abs=2e-5)
    assert result.flags == ()
    assert not result.double_impact
    assert result.fit_error < 0.01


@pytest.mark.parametrize("inertia, stiffness, amplitude_deg", [
    (0.1557, 22_000.0, 0.2), (0.359, 9_000.0, 3.0), (0.5233, 14_000.0, 1.0)])
def test_synthetic_across_the_test_plan(inertia, stiffness, amplitude_deg):
    drop = SyntheticDrop(inertia_kgm2=inertia, stiffness_nm_per_rad=stiffness, amplitude_deg=amplitude_deg,
                         damping_ratio=1.3, ringing_fraction=0.3, seed=5)
    check_accuracy(drop, extract(drop.signals()))


def test_uncertainties_match_the_scatter():
    """Standard uncertainties from the fit agree with the scatter over noise realisations."""
    results = [extract(SyntheticDrop(sample_rate_hz=2048.0, seed=seed).signals()) for seed in range(40)]
    truth = SyntheticDrop()
    for name, true in [("stiffness_nm_per_rad", truth.stiffness_nm_per_rad), ("damping_ratio", truth.damping_ratio),
                       ("frequency_hz", truth.omega / (2 * np.pi))]:
        values = np.array([getattr(r, name) for r in results])
        predicted = np.mean([r.std[name] for r in results])
        assert 0.65 < values.std(ddof=1) / predicted < 1.5, name
        assert abs(values.mean() - true) < 4 * predicted / np.sqrt(len(values)), name


def test_without_force_channel_onset_from_angle():
    drop = SyntheticDrop(ringing_fraction=0.3, seed=2)
    signals = dataclasses.replace(drop.signals(), impact_force_n=None)
    result = extract(signals)
    check_accuracy(drop, result)
    assert "double_impact_unchecked" in result.flags
    assert math.isnan(result.impact_impulse_ns)


def test_negative_sign_convention():
    drop = SyntheticDrop(seed=4)
    s = drop.signals()
    flipped = dataclasses.replace(s, angle_rad=-s.angle_rad, torque_nm=-s.torque_nm, impact_force_n=-s.impact_force_n)
    result = extract(flipped)
    check_accuracy(drop, result)
    assert result.stiffness_torque_nm_per_rad == pytest.approx(drop.stiffness_nm_per_rad, rel=0.02)


def test_second_impact_is_flagged():
    drop = SyntheticDrop(second_impact_after_s=0.012, seed=1)
    result = extract(drop.signals())
    assert result.double_impact and "double_impact" in result.flags
    assert result.second_impact_after_s == pytest.approx(0.012, abs=5e-4)
    low = dataclasses.replace(drop, sample_rate_hz=2048.0)
    assert extract(low.signals()).double_impact
    # a contact long after the first period does not disturb the first-cycle fit: reported, not flagged
    late_drop = dataclasses.replace(drop, second_impact_after_s=0.09)
    late = extract(late_drop.signals())
    assert not late.double_impact and late.second_impact_after_s == pytest.approx(0.09, abs=5e-4)
    assert extract(late_drop.signals(), window="3-cycles").double_impact  # inside the window it matters


def test_clipping_is_flagged():
    s = SyntheticDrop(seed=3).signals()
    clipped = dataclasses.replace(s, angle_rad=np.minimum(s.angle_rad, np.quantile(s.angle_rad, 0.97)))
    assert "clipping" in extract(clipped).flags
    assert "clipping" not in extract(s).flags


def test_too_few_samples_per_period_is_flagged():
    drop = SyntheticDrop(sample_rate_hz=500.0, pretrigger_s=0.05, duration_s=0.4, seed=3)
    result = extract(drop.signals())
    assert "too_few_samples_per_period" in result.flags
    assert result.samples_per_period < 20


def test_poor_fit_is_flagged():
    s = SyntheticDrop(seed=3).signals()
    distorted = dataclasses.replace(s, angle_rad=s.angle_rad + 0.3 * DEG * np.sin(2 * np.pi * 170 * s.time_s)
                                    * (s.time_s > 0.02))
    result = extract(distorted)
    assert "poor_fit" in result.flags and result.fit_error > 0.05


# --- windows -------------------------------------------------------------------------------

def test_window_parse():
    assert Window.parse("first-cycle") == Window(cycles=1.0)
    assert Window.parse("2-cycles") == Window(cycles=2.0)
    assert Window.parse("0.05") == Window(cycles=None, seconds=0.05)
    for bad in ("fist-cycle", "-2-cycles", "0", "abc"):
        with pytest.raises(DroptowerError, match="window"):
            Window.parse(bad)


def test_two_cycle_window_and_seconds_window():
    drop = SyntheticDrop(seed=6)
    period = 2 * np.pi / drop.omega
    two = extract(drop.signals(), window="2-cycles")
    check_accuracy(drop, two)
    assert two.window_end_s == pytest.approx(2 * period, rel=0.01)
    seconds = extract(drop.signals(), window="0.03")
    assert seconds.window_end_s == pytest.approx(0.03)
    check_accuracy(drop, seconds)


def test_window_shorter_than_three_quarters_is_refused():
    with pytest.raises(DroptowerError, match="shorter than 3/4"):
        extract(SyntheticDrop().signals(), window="0.015")


def test_window_beyond_the_record_is_flagged_short():
    drop = SyntheticDrop(duration_s=0.02 + 0.9 * 2 * np.pi / SyntheticDrop().omega, seed=8)
    result = extract(drop.signals())
    assert "short_window" in result.flags


def test_record_shorter_than_three_quarters_period_after_impact():
    drop = SyntheticDrop(duration_s=0.02 + 0.6 * 2 * np.pi / SyntheticDrop().omega)
    with pytest.raises(DroptowerError, match="less than 3/4 of the oscillation period"):
        extract(drop.signals())
    tiny = SyntheticDrop(duration_s=0.028)
    with pytest.raises(DroptowerError, match="never swings back"):
        extract(tiny.signals())


# --- bad input: one line naming the file and the problem ------------------------------------

def _signals(**changes) -> DropSignals:
    s = SyntheticDrop(seed=9).signals()
    s.source = Path("drop_017.csv")
    return dataclasses.replace(s, **changes)


@pytest.mark.parametrize("make, message", [
    (lambda s: {"angle_rad": np.full_like(s.angle_rad, 0.1)}, "angle_rad: constant signal"),
    (lambda s: {"impact_force_n": np.random.default_rng(0).normal(0, 20, s.time_s.size)}, "no impact found"),
    (lambda s: {"impact_force_n": None, "angle_rad": np.random.default_rng(0).normal(0, 1e-4, s.time_s.size)},
     "no impact found"),
    (lambda s: {"torque_nm": np.where(np.arange(s.time_s.size) == 500, np.nan, s.torque_nm)}, "NaN"),
    (lambda s: {"time_s": np.where(np.arange(s.time_s.size) == 300, 0.0, s.time_s)}, "non-monotonic"),
    (lambda s: {"time_s": np.where(np.arange(s.time_s.size) == 300, s.time_s[299], s.time_s)}, "duplicated"),
    (lambda s: {"metadata": {}}, "no rotating inertia"),
])
def test_bad_input_is_one_line_naming_the_file(make, message):
    signals = _signals()
    with pytest.raises(DroptowerError) as info:
        extract(dataclasses.replace(signals, **make(signals)))
    text = str(info.value)
    assert "\n" not in text and text.startswith("drop_017.csv") and message in text


def test_impact_at_start_of_record_has_no_pretrigger():
    drop = SyntheticDrop(pretrigger_s=0.0002)
    with pytest.raises(DroptowerError, match="after a pre-trigger"):
        extract(drop.signals())


def test_without_torque_channel():
    drop = SyntheticDrop(seed=12)
    result = extract(dataclasses.replace(drop.signals(), torque_nm=None))
    check_accuracy(drop, result)
    for name in ("stiffness_torque_nm_per_rad", "stiffness_deviation", "torque_amplitude_nm", "torque_offset_nm"):
        assert math.isnan(getattr(result, name)), name
    assert "stiffness_torque_nm_per_rad" not in result.std


def test_sample_rate_too_low_for_the_oscillation():
    drop = SyntheticDrop(sample_rate_hz=150.0, pretrigger_s=0.2, duration_s=0.6, pulse_s=3e-4, seed=1)
    with pytest.raises(DroptowerError, match="too low"):
        extract(drop.signals())
