"""Lab-style evaluation of steady-state cycles on synthetic records with known answers."""
import math

import numpy as np
import pytest

from droptower.errors import DroptowerError
from droptower.rheology.loader import parse_coupling
from droptower.servo import drop_tower_equivalent_damping_ratio, evaluate_cycles
from droptower.servo.evaluate import smoothing_window


def _record(fs, f, amp, k1, k2, *, mean_angle=0.0, mean_torque=0.0, extra=None, cycles=8):
    """A sine angle and the torque K' phi + (K''/omega) dphi/dt (+ extra(t)), the elastoslide paper, eq. 5."""
    w = 2 * np.pi * f
    t = np.arange(int(cycles / f * fs) + 1) / fs
    phi = amp * np.sin(w * t + 0.3)
    torque = k1 * phi + k2 * amp * np.cos(w * t + 0.3) + mean_torque
    if extra is not None:
        torque = torque + extra(t)
    return t, phi + mean_angle, torque


@pytest.mark.parametrize("fs,f", [(2048.0, 30.0), (2048.0, 7.3), (2048.0, 100.0), (500.0, 3.0)])
@pytest.mark.parametrize("smooth", [True, False])
def test_first_harmonic_of_an_elliptic_loop_is_exact(fs, f, smooth):
    # non-integer samples per cycle: the whole-cycle resampling keeps the elastoslide paper, eq. 6 exact
    k1, k2, amp = 12000.0, 3000.0, 0.02
    t, phi, torque = _record(fs, f, amp, k1, k2, mean_angle=0.01, mean_torque=-40.0)
    ev = evaluate_cycles(t, phi, torque, f, 2.0 / f, 5, smooth=smooth)
    k_star = complex(k1, k2)
    assert abs(ev.complex_stiffness_nm_per_rad / k_star - 1) < 2e-5
    assert ev.loss_factor == pytest.approx(k2 / k1, rel=1e-4)
    assert ev.loss_angle_rad == pytest.approx(math.atan2(k2, k1), abs=2e-5)
    assert ev.mean_angle_rad == pytest.approx(0.01, abs=1e-8)
    assert ev.mean_torque_nm == pytest.approx(-40.0, abs=1e-6 * abs(k_star) * amp)
    # the smoothing filter's gain (one-eighth cycle, cubic) is within 2e-4 of 1
    assert ev.angle_amplitude_rad == pytest.approx(amp, rel=2e-4)
    assert ev.torque_amplitude_nm == pytest.approx(abs(k_star) * amp, rel=2e-4)
    # elliptic loop: W_D = pi K'' phi^2 exactly, so psi = 2 pi eta / sqrt(1 + eta^2) (~ 2 pi eta)
    assert ev.damping_work_j == pytest.approx(math.pi * ev.loss_stiffness_nm_per_rad * ev.angle_amplitude_rad ** 2,
                                              rel=3e-5)
    eta = k2 / k1
    assert ev.relative_damping_psi == pytest.approx(2 * math.pi * eta / math.sqrt(1 + eta * eta), rel=3e-5)
    assert ev.steady_state_deviation < 1e-5
    assert ev.smoothing_window_samples == (smoothing_window(fs, f) if smooth else 0)


def test_loop_area_is_measured_geometrically_not_from_the_fit():
    # odd torque harmonics change neither the first harmonic nor the loop area of a sine test,
    # but they change the loop's shape and its peaks: the polygon integral must see through them
    f, fs, amp, k1, k2 = 10.0, 2048.0, 0.01, 8000.0, 2000.0

    def extra(t):
        return 25.0 * np.sin(3 * 2 * np.pi * f * t + 1.0) + 10.0 * np.cos(5 * 2 * np.pi * f * t)

    t, phi, torque = _record(fs, f, amp, k1, k2, extra=extra)
    ev = evaluate_cycles(t, phi, torque, f, 1.0 / f, 5, smooth=False)  # smoothing would scale W_D by ~1 - 2e-4
    assert abs(ev.complex_stiffness_nm_per_rad / complex(k1, k2) - 1) < 1e-5
    assert ev.damping_work_j == pytest.approx(math.pi * k2 * amp ** 2, rel=2e-5)
    # but T_hat now differs from |K*| phi_hat, and psi with it
    assert abs(ev.torque_amplitude_nm / (abs(complex(k1, k2)) * amp) - 1) > 1e-3


def test_dual_frequency_components():
    fs, f1, f2, a1, a2 = 2048.0, 5.0, 7.5, 0.01, 0.02
    k1, k2 = complex(9000, 1500), complex(9500, 2500)
    t = np.arange(int(6 / 2.5 * fs) + 1) / fs
    w1, w2 = 2 * np.pi * f1, 2 * np.pi * f2
    phi = a1 * np.sin(w1 * t) + a2 * np.sin(w2 * t)
    torque = (k1.real * a1 * np.sin(w1 * t) + k1.imag * a1 * np.cos(w1 * t)
              + k2.real * a2 * np.sin(w2 * t) + k2.imag * a2 * np.cos(w2 * t))
    ev = evaluate_cycles(t, phi, torque, 2.5, 0.4, 3, components_hz=[f1, f2])
    got = [h.complex_stiffness_nm_per_rad for h in ev.harmonics]
    assert abs(got[0] / k1 - 1) < 1e-5 and abs(got[1] / k2 - 1) < 1e-5
    assert [h.angle_amplitude_rad for h in ev.harmonics] == pytest.approx([a1, a2], rel=1e-4)
    # per 2.5 Hz cycle: 2 cycles at 5 Hz and 3 at 7.5 Hz, each pi K'' a^2; the smoothing filter's
    # gain (1 - 1e-4 on each signal) scales the loop area by 1 - 2e-4
    assert ev.damping_work_j == pytest.approx(math.pi * (2 * k1.imag * a1 ** 2 + 3 * k2.imag * a2 ** 2), rel=3e-4)
    assert [r["frequency_hz"] for r in ev.records()] == [f1, f2]


def test_discrete_kelvin_voigt_is_evaluated_exactly():
    # sampled at 500 Hz with no sub-steps, the kernels' dashpot reads the rate of the last step:
    # K = k + c (1 - exp(-i w h)) / h exactly. The evaluation must return that to round-off.
    k, c, fs, f = 1.0e4, 10.0, 500.0, 20.0
    coupling = parse_coupling({"element": [{"kind": "spring", "stiffness": k}, {"kind": "dashpot", "damping": c}]})
    t = np.arange(int(2.0 * fs) + 1) / fs
    phi = 0.01 * np.sin(2 * np.pi * f * t)
    ev = evaluate_cycles(t, phi, coupling.respond(phi, 1 / fs), f, 0.5, 20)
    w, h = 2 * np.pi * f, 1 / fs
    exact = k + c * (1 - np.exp(-1j * w * h)) / h
    assert abs(ev.complex_stiffness_nm_per_rad / exact - 1) < 1e-9


def test_steady_state_deviation_flags_a_drifting_record():
    f, fs = 10.0, 2048.0
    t, phi, torque = _record(fs, f, 0.01, 1e4, 2e3)
    grow = torque * (1 + 0.1 * t)  # stiffness still changing: not steady
    assert evaluate_cycles(t, phi, torque, f, 0.2, 5).steady_state_deviation < 1e-5
    assert evaluate_cycles(t, phi, grow, f, 0.2, 5).steady_state_deviation > 0.01


def test_smoothing_window_is_an_eighth_of_a_cycle_or_off():
    assert smoothing_window(2048.0, 1.0) == 257
    assert smoothing_window(2048.0, 30.0) == 9
    assert smoothing_window(2048.0, 64.0) == 5
    assert smoothing_window(2048.0, 100.0) == 0  # 2.6 samples: too few, no smoothing


def test_drop_tower_equivalent_damping_ratio_matches_the_theory():
    # docs/theory.md#damping-measures: a linear Kelvin-Voigt coupling at its damped frequency, r = delta / omega
    # docs/theory.md#damping-measures quotes d_ratio to two decimals: 1.25 at r = 0.10, 0.44 at 0.05, 1.76 at 0.12
    for r, d in [(0.10, 1.25), (0.05, 0.44), (0.12, 1.76)]:
        eta = 2 * r / (1 + r * r)
        assert float(drop_tower_equivalent_damping_ratio(eta)) == pytest.approx(d, abs=0.01)
    assert float(drop_tower_equivalent_damping_ratio(0.0)) == 0.0
    assert math.isnan(float(drop_tower_equivalent_damping_ratio(1.2)))
    r = np.linspace(0.01, 0.99, 50)
    back = drop_tower_equivalent_damping_ratio(2 * r / (1 + r * r))
    np.testing.assert_allclose(back, 0.5 * np.expm1(4 * np.pi * r), rtol=1e-9)


@pytest.mark.parametrize("case,match", [
    ("coarse", "too coarse"),
    ("short", "does not cover"),
    ("jitter", "not uniformly sampled"),
    ("nan", "NaN"),
    ("length", "differ in length"),
])
def test_bad_records_are_one_line_errors(case, match):
    fs, f = 2048.0, 10.0
    t, phi, torque = _record(fs, f, 0.01, 1e4, 2e3)
    kw = dict(frequency_hz=f, start_s=0.2, cycles=5)
    if case == "coarse":
        kw["frequency_hz"] = 150.0
        kw["start_s"] = 0.01
    elif case == "short":
        kw["cycles"] = 8
    elif case == "jitter":
        t = t.copy()
        t[100] += 0.3 / fs
    elif case == "nan":
        torque = torque.copy()
        torque[5] = np.nan
    elif case == "length":
        torque = torque[:-1]
    with pytest.raises(DroptowerError, match=match) as err:
        evaluate_cycles(t, phi, torque, **kw)
    assert "\n" not in str(err.value)
