"""Exact closed forms through the servo bench (histories -> coupling -> lab evaluation).

Tolerances, sampled at 2048 Hz (the paper's bench) and simulated at >= 38.4 kHz and >= 4096
steps per cycle (the bench's defaults):
- Kelvin-Voigt, Maxwell, generalized Maxwell: |K*_bench - K*| <= 0.2 % of |K*| (and K', K''
  each within 0.2 % where they exceed a tenth of |K*|), 1 to 100 Hz;
- Pfeffer K*(Omega) of docs/theory.md#pfeffer (Scheiblegger et al.'s (2013) time/frequency agreement): 0.5 %;
- linear models: W_D = pi K'' phi_hat^2 and psi = 2 pi eta / sqrt(1 + eta^2) within 1e-4;
- Coulomb Prandtl element: loop area 4 f (phi_hat - f/k) within 1e-3 up to 10 Hz (the
  one-eighth-cycle smoothing alone scales loop areas by 1 - 2e-4); at 60 Hz the kinked loop's
  harmonics alias at 2048 Hz (3e-3), sampled at 38.4 kHz 5e-4.
The measured errors are 10-100 times smaller.
"""
import math

import numpy as np
import pytest

from droptower.errors import DroptowerError
from droptower.rheology.elements import Pfeffer
from droptower.rheology.loader import parse_coupling
from droptower.servo import evaluate_history, run_bench, run_grid
from droptower.servo import histories as H
from droptower.servo.bench import run_records

FREQS = [1.0, 10.0, 30.0, 100.0]
AMPS = [0.004, 0.02]


def _coupling(*elements):
    return parse_coupling({"name": "test", "element": list(elements)})


def _k_bench(df):
    return df["storage_stiffness_nm_per_rad"].to_numpy() + 1j * df["loss_stiffness_nm_per_rad"].to_numpy()


def _assert_complex_close(got, want, rel):
    got, want = np.asarray(got), np.asarray(want)
    assert np.all(np.abs(got - want) <= rel * np.abs(want)), np.abs(got / want - 1)
    for part in (np.real, np.imag):  # each part where it is not a negligible share of |K*|
        big = np.abs(part(want)) >= 0.1 * np.abs(want)
        np.testing.assert_allclose(part(got)[big], part(want)[big], rtol=rel)


def _omega(df):
    return 2 * np.pi * df["frequency_hz"].to_numpy()


def test_kelvin_voigt_storage_k_loss_c_omega():
    k, c = 12000.0, 15.0
    df = run_grid(_coupling({"kind": "spring", "stiffness": k}, {"kind": "dashpot", "damping": c}), AMPS, FREQS)
    assert len(df) == len(AMPS) * len(FREQS)
    _assert_complex_close(_k_bench(df), k + 1j * c * _omega(df), 2e-3)


@pytest.mark.parametrize("tau", [2e-4, 2e-3, 2e-2, 0.2])
def test_maxwell_closed_form(tau):
    k = 5000.0
    df = run_grid(_coupling({"kind": "maxwell", "stiffness": k, "damping": k * tau}), [0.01], FREQS)
    wt = _omega(df) * tau
    want = k * wt ** 2 / (1 + wt ** 2) + 1j * k * wt / (1 + wt ** 2)
    _assert_complex_close(_k_bench(df), want, 2e-3)
    assert df["steady_state_deviation"].max() < 1e-3


def test_generalized_maxwell_closed_form():
    k_inf, terms = 8000.0, [(6000.0, 0.05), (4000.0, 0.004), (3000.0, 0.0005)]
    df = run_grid(_coupling({"kind": "prony", "equilibrium_stiffness": k_inf,
                             "terms": [{"stiffness": s, "relaxation_time": t} for s, t in terms]}), AMPS, FREQS)
    w = _omega(df)
    want = k_inf + sum(s * (1j * w * t) / (1 + 1j * w * t) for s, t in terms)
    _assert_complex_close(_k_bench(df), want, 2e-3)


@pytest.mark.parametrize("alpha,beta,gamma", [(0.5, 0.3, 0.01), (2.0, 0.0, 0.002), (1.0, 3.0, 0.05),
                                              (0.2, 1.0, 0.001), (5.0, 0.5, 0.02)])
def test_pfeffer_time_domain_equals_its_complex_stiffness(alpha, beta, gamma):
    # Scheiblegger et al. 2013: time-domain and frequency-domain results must agree for the linear model
    el = Pfeffer(kind="pfeffer", k1=10000.0, alpha=alpha, beta=beta, gamma=gamma)
    freqs = [1.0, 5.0, 20.0, 60.0, 100.0]
    df = run_grid(_coupling(el.model_dump()), [0.01], freqs)
    want = el.complex_stiffness(_omega(df))
    assert np.all(np.abs(_k_bench(df) / want - 1) <= 5e-3)
    np.testing.assert_allclose(df["loss_angle_deg"], np.degrees(np.angle(want)), atol=0.5e-2 * 57.3)


def test_linear_loop_area_and_relative_damping():
    # elliptic loop: W_D = pi K'' phi_hat^2 exactly, psi = W_D / (T_hat phi_hat / 2)
    # = 2 pi eta / sqrt(1 + eta^2), i.e. psi ~ 2 pi eta to first order (docs/theory.md#damping-measures)
    coupling = _coupling({"kind": "spring", "stiffness": 9000.0}, {"kind": "maxwell", "stiffness": 6000.0,
                                                                   "damping": 60.0})
    df = run_grid(coupling, AMPS, FREQS)
    eta = df["loss_factor"].to_numpy()
    np.testing.assert_allclose(df["damping_work_j"],
                               np.pi * df["loss_stiffness_nm_per_rad"] * df["angle_amplitude_rad"] ** 2, rtol=1e-4)
    np.testing.assert_allclose(df["relative_damping_psi"], 2 * np.pi * eta / np.sqrt(1 + eta ** 2), rtol=1e-4)
    np.testing.assert_allclose(df["angle_amplitude_rad"], df["amplitude_rad"], rtol=2e-4)
    assert np.all(np.abs(df["relative_damping_psi"] / (2 * np.pi * eta) - 1) < eta ** 2 / 2 + 1e-4)
    # the drop-tower-equivalent ratio is a different number (docs/theory.md#damping-measures): it is labelled so
    r = (1 - np.sqrt(1 - eta ** 2)) / eta
    np.testing.assert_allclose(df["drop_tower_equivalent_damping_ratio"], 0.5 * np.expm1(4 * np.pi * r), rtol=1e-9)


@pytest.mark.parametrize("freqs,fs,rtol", [
    ([1.0, 10.0], 2048.0, 1e-3),
    # 34 samples per cycle: the loop's kinks put harmonics ~ 1/n^2 near n = 33, 35, which alias
    # onto the fundamental; the error scales as (f / fs)^2 (measured 1.7e-3 here)
    ([60.0], 2048.0, 3e-3),
    # the same tests sampled at 38.4 kHz: only the smoothing gain (1 - 2e-4) is left
    ([60.0, 100.0], 38400.0, 5e-4),
])
def test_coulomb_prandtl_loop_area_closed_form(freqs, fs, rtol, regression):
    k, f = 20000.0, 50.0
    amps = np.array([1.5, 3.0, 10.0]) * f / k
    df = run_grid(_coupling({"kind": "prandtl", "stiffness": k, "yield_torque": f}), amps, freqs, sample_rate_hz=fs)
    a = df["amplitude_rad"].to_numpy()
    closed = 4 * f * (a - f / k)
    np.testing.assert_allclose(df["damping_work_j"], closed, rtol=rtol)
    # the measured largest error, stored (tests/regression.py); the bench is deterministic, so it
    # reproduces to round-off, far below 1e-6 of an error of >= 1e-5
    regression.check("max_relative_loop_area_error", np.max(np.abs(df["damping_work_j"] / closed - 1)), rel=1e-6)


def test_coulomb_prandtl_peak_torque_unsmoothed():
    # the one-eighth-cycle smoothing rounds the corner where a slider starts to slip and lifts
    # the smoothed peak above f (by up to 5 % at 10 times the slip angle); the unsmoothed,
    # finely sampled record shows the model's own peak, the yield torque
    k, f = 20000.0, 50.0
    amps = np.array([1.5, 3.0, 10.0]) * f / k
    coupling = _coupling({"kind": "prandtl", "stiffness": k, "yield_torque": f})
    raw = run_grid(coupling, amps, [1.0, 10.0], sample_rate_hz=38400.0, smooth=False)
    np.testing.assert_allclose(raw["torque_amplitude_nm"], f, rtol=1e-4)
    smoothed = run_grid(coupling, amps, [1.0, 10.0])
    assert np.all(smoothed["torque_amplitude_nm"] > f)


def test_coulomb_prandtl_below_slip_is_a_spring():
    k, f = 20000.0, 50.0
    # below the slip angle the element is a spring: no loop
    low = run_grid(_coupling({"kind": "prandtl", "stiffness": k, "yield_torque": f}), [0.5 * f / k], [10.0])
    assert abs(low["damping_work_j"].iloc[0]) < 1e-6 * f * f / k
    assert low["storage_stiffness_nm_per_rad"].iloc[0] == pytest.approx(k, rel=1e-6)


def test_preload_is_reached_by_the_mean_angle():
    k, c, preload = 10000.0, 10.0, 300.0
    df = run_grid(_coupling({"kind": "spring", "stiffness": k}, {"kind": "dashpot", "damping": c}), AMPS,
                  [5.0, 20.0], preload_nm=preload)
    np.testing.assert_allclose(df["mean_torque_nm"], preload, atol=1e-4 * preload)
    np.testing.assert_allclose(df["offset_rad"], preload / k, rtol=1e-4)
    _assert_complex_close(_k_bench(df), k + 1j * c * _omega(df), 2e-3)
    # a relaxing branch carries no static torque: the mean angle is set by the spring alone
    relax = run_grid(_coupling({"kind": "spring", "stiffness": k}, {"kind": "maxwell", "stiffness": 5000.0,
                                                                    "damping": 25.0}), [0.01], [10.0],
                     preload_nm=-preload)
    assert relax["offset_rad"].iloc[0] == pytest.approx(-preload / k, rel=1e-3)


def test_run_records_are_the_signals_behind_the_table():
    """The records of a preloaded grid, sampled at the acquisition rate, follow the Kelvin-Voigt
    law T = k phi + c phi' over the whole test and belong to the table's rows."""
    k, c, preload = 10000.0, 10.0, 300.0
    coupling = _coupling({"kind": "spring", "stiffness": k}, {"kind": "dashpot", "damping": c})
    df = run_grid(coupling, AMPS, [5.0, 20.0], preload_nm=preload)
    records = run_records(coupling, AMPS, [5.0, 20.0], preload_nm=preload)
    assert [(r.amplitude_rad, r.frequency_hz, r.preload_nm, r.offset_rad) for r in records] == list(
        zip(df["amplitude_rad"], df["frequency_hz"], df["preload_nm"], df["offset_rad"]))
    for r in records:
        np.testing.assert_allclose(np.diff(r.time_s), 1 / 2048, rtol=1e-9)
        assert r.angle_rad.shape == r.torque_nm.shape == r.time_s.shape
        # phi' by central differences: relative error (omega / 2048)^2 / 6 < 7e-4 (< 0.02 N*m), and
        # h |jump of phi''| / 4 < 0.02 N*m where the preload ramp ends; the fine step's half-step
        # lag of the dashpot, c |phi''| h_fine / 2 < 0.01 N*m
        rate = (r.angle_rad[2:] - r.angle_rad[:-2]) / (r.time_s[2:] - r.time_s[:-2])
        np.testing.assert_allclose(r.torque_nm[1:-1], k * r.angle_rad[1:-1] + c * rate, rtol=0, atol=0.03)
        assert r.angle_rad.max() == pytest.approx(r.offset_rad + r.amplitude_rad, rel=1e-3)


def test_preload_without_static_stiffness_is_an_error():
    coupling = _coupling({"kind": "prandtl", "stiffness": 1e4, "yield_torque": 100.0})
    with pytest.raises(DroptowerError, match="preload"):
        run_grid(coupling, [0.02], [5.0], preload_nm=30.0)


def test_batched_rows_equal_single_runs():
    coupling = _coupling({"kind": "spring", "stiffness": 1000.0},
                         {"kind": "masing", "stiffness": 20000.0, "max_yield_torque": 100.0, "alpha": 3.0})
    both = run_grid(coupling, [0.005, 0.02], [10.0])
    one = run_grid(coupling, [0.02], [10.0])
    np.testing.assert_allclose(both.iloc[1][["storage_stiffness_nm_per_rad", "damping_work_j"]].to_numpy(float),
                               one.iloc[0][["storage_stiffness_nm_per_rad", "damping_work_j"]].to_numpy(float),
                               rtol=1e-12)
    # the Masing model softens and its loop widens with amplitude
    assert both["dynamic_stiffness_nm_per_rad"].iloc[0] > both["dynamic_stiffness_nm_per_rad"].iloc[1]


def test_sweeps_and_dual_frequency_through_a_coupling():
    terms = [(5000.0, 0.01), (3000.0, 0.001)]
    coupling = _coupling({"kind": "prony", "equilibrium_stiffness": 10000.0,
                          "terms": [{"stiffness": s, "relaxation_time": t} for s, t in terms]})

    def k_star(f):
        w = 2 * np.pi * f
        return 10000.0 + sum(s * (1j * w * t) / (1 + 1j * w * t) for s, t in terms)

    fs = 38400.0  # simulated and evaluated at the drop tower's rate, no sub-steps
    sweep = H.frequency_sweep([2.0, 8.0, 25.0], 0.01, fs, run_in_cycles=4, cycles=3)
    evs = evaluate_history(sweep, coupling.respond(sweep.angle_rad, sweep.dt_s))
    for ev, f in zip(evs, [2.0, 8.0, 25.0]):
        assert abs(ev.complex_stiffness_nm_per_rad / k_star(f) - 1) < 2e-3
    # the elastoslide paper's dual-frequency test: 5 Hz + 7.5 Hz evaluated over the 2.5 Hz common period
    dual = H.dual_frequency((5.0, 7.5), (0.01, 0.02), fs, run_in_cycles=3, cycles=3)
    (ev,) = evaluate_history(dual, coupling.respond(dual.angle_rad, dual.dt_s))
    for h in ev.harmonics:
        assert abs(h.complex_stiffness_nm_per_rad / k_star(h.frequency_hz) - 1) < 2e-3
    # a linear model's loop area is the sum of its components' (2 and 3 cycles per 2.5 Hz period)
    w_d = math.pi * (2 * k_star(5.0).imag * 0.01 ** 2 + 3 * k_star(7.5).imag * 0.02 ** 2)
    assert ev.damping_work_j == pytest.approx(w_d, rel=1e-3)


def test_bench_result_keeps_loops_and_accepts_a_file(tmp_path):
    path = tmp_path / "c.toml"
    path.write_text('name = "kv"\n[[element]]\nkind = "spring"\nstiffness = 5000.0\n'
                    '[[element]]\nkind = "dashpot"\ndamping = 5.0\n')
    result = run_bench(path, [0.01], [10.0, 20.0])
    assert len(result.evaluations) == 2
    ev = result.evaluations[0]
    assert ev.loop_angle_rad.shape == ev.loop_torque_nm.shape and ev.loop_angle_rad.size > 100
    assert np.ptp(ev.loop_angle_rad) == pytest.approx(0.02, rel=1e-3)


@pytest.mark.parametrize("kw,match", [
    (dict(frequencies_hz=[10.0, 120.0]), "too coarse"),
    (dict(amplitudes_rad=[0.01, -0.01]), "amplitude"),
    (dict(frequencies_hz=[]), "frequency"),
    (dict(cycles=0), "cycles"),
])
def test_bad_grid_is_a_one_line_error(kw, match):
    args = dict(amplitudes_rad=[0.01], frequencies_hz=[10.0])
    args.update(kw)
    with pytest.raises(DroptowerError, match=match) as err:
        run_grid(_coupling({"kind": "spring", "stiffness": 1e3}), **args)
    assert "\n" not in str(err.value)
