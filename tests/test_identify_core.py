"""The identification machinery: records -> segments (checks, lead-in), load cycles, the batched
least-squares engine (closed-form linear regression as reference) and its error measures."""
from __future__ import annotations

import numpy as np
import pytest

from droptower.errors import DroptowerError
from droptower.identify.cycles import blocks, evaluate_block, local_amplitude_frequency, turning_points
from droptower.identify.data import DataScale, make_segment
from droptower.identify.families import OverlayFamily
from droptower.identify.fit import least_squares_fit, metrics
from droptower.rheology import Coupling
from droptower.servo import histories as H

from test_identify_helpers import FS, coupling

D = np.radians


# ------------------------------------------------------------------ records
def test_segment_checks_one_line_errors():
    t = np.arange(400) / FS
    x = D(1.0) * np.sin(2 * np.pi * 5 * t)
    with pytest.raises(DroptowerError, match="too short: 10 samples"):
        make_segment(t[:10], x[:10], x[:10], file="a.csv")
    with pytest.raises(DroptowerError, match="never reverses") as err:
        make_segment(t, np.linspace(0, 0.1, t.size), t, file="ramp.csv")
    assert str(err.value).startswith("ramp.csv: ") and "\n" not in str(err.value)
    jitter = t.copy()
    jitter[100:] += 0.3 / FS
    with pytest.raises(DroptowerError, match="time step is not constant"):
        make_segment(jitter, x, x)
    with pytest.raises(DroptowerError, match="differ in length"):
        make_segment(t, x, x[:-1])


def test_preloaded_record_gets_a_lead_in_that_is_not_compared():
    t = np.arange(512) / FS
    x = D(2.0) + D(0.5) * np.sin(2 * np.pi * 4 * t)
    seg = make_segment(t, x, 3.0 * x, lead_in_s=0.25)
    assert seg.lead_in == int(0.25 * FS) - 1
    assert seg.angle_rad[0] == pytest.approx(0.0, abs=D(2.0) * 1e-3)
    np.testing.assert_array_equal(seg.measured_angle, x)
    assert not seg.compared[:seg.lead_in].any() and seg.compared[seg.lead_in:].all()
    assert np.all(np.diff(seg.angle_rad[:seg.lead_in + 1]) >= 0)  # a monotonic ramp up to the preload


# ------------------------------------------------------------------ cycles
def test_blocks_of_an_amplitude_sweep_and_their_lab_evaluation():
    h = H.amplitude_sweep(D(np.array([0.5, 1.0, 2.0])), 10.0, 2048.0, run_in_cycles=4, cycles=5)
    rng = np.random.default_rng(1)
    x = h.angle_rad + rng.normal(0, D(0.005), h.angle_rad.size)
    kv = coupling({"kind": "spring", "stiffness": 1000.0}, {"kind": "dashpot", "damping": 5.0})
    torque = kv.respond(x, h.dt_s)
    found = blocks(x, h.dt_s)
    assert [round(np.degrees(b.amplitude_rad), 2) for b in found] == pytest.approx([0.5, 1.0, 2.0], abs=0.02)
    for b in found:
        assert b.frequency_hz == pytest.approx(10.0, rel=1e-3)
        ev = evaluate_block(x, torque, h.dt_s, b)
        # Kelvin-Voigt: K' = k, K'' = c omega (the dashpot reads the step's rate: within 1 %)
        assert ev.storage_stiffness_nm_per_rad == pytest.approx(1000.0, rel=0.01)
        assert ev.loss_stiffness_nm_per_rad == pytest.approx(5.0 * 2 * np.pi * 10.0, rel=0.01)
    amp, freq = local_amplitude_frequency(x, h.dt_s)
    late = slice(-int(0.3 * FS * 4), -int(0.05 * FS * 4))
    assert np.median(np.degrees(amp[late])) == pytest.approx(2.0, rel=0.02)
    assert np.median(freq[late]) == pytest.approx(10.0, rel=0.02)


def test_turning_points_ignore_noise():
    rng = np.random.default_rng(0)
    t = np.arange(4096) / 2048.0
    x = np.sin(2 * np.pi * 3 * t) + rng.normal(0, 0.01, t.size)
    tp = turning_points(x)
    assert tp.size == 12  # 6 periods: 6 maxima, 6 minima
    assert np.all(np.abs(np.abs(x[tp]) - 1) < 0.05)


# ------------------------------------------------------------------ least squares engine
def _kv_data(noise: float, seed: int = 0):
    rng = np.random.default_rng(seed + 100)  # not the profile's own generator
    h = H.random_profile(D(1.0), (0.5, 20.0), 6.0, FS, seed=seed)
    k, c = 12000.0, 25.0
    x = h.angle_rad
    rate = np.diff(x, prepend=0.0) / h.dt_s  # the core's dashpot: the rate of the step
    y = k * x + c * rate + rng.normal(0, noise, x.size)
    return make_segment(h.time_s, x, y), np.column_stack([x, rate]), y, (k, c)


def test_linear_fit_equals_ordinary_least_squares_with_its_standard_errors():
    seg, X, y, truth = _kv_data(noise=2.0)
    family = OverlayFamily(DataScale.of([seg]))
    r = least_squares_fit(family, [seg], family.initial())
    beta, *_ = np.linalg.lstsq(X, y, rcond=None)
    resid = y - X @ beta
    cov = resid @ resid / (y.size - 2) * np.linalg.inv(X.T @ X)
    assert r.converged
    np.testing.assert_allclose(r.values, beta, rtol=1e-6)
    # the engine's errors: from the Jacobian, inflated by sqrt((1+r1)/(1-r1)) for white-noise r1 ~ 0
    np.testing.assert_allclose(r.std_error, np.sqrt(np.diag(cov)), rtol=0.05)
    assert abs(r.metrics.residual_lag1) < 0.05
    assert r.metrics.rmse_nm == pytest.approx(np.sqrt(np.mean(resid ** 2)), rel=1e-6)
    assert r.metrics.nrmse == pytest.approx(r.metrics.rmse_nm / np.max(np.abs(y)))


def test_every_jacobian_is_one_batched_core_call(monkeypatch):
    segs = [_kv_data(noise=1.0, seed=s)[0] for s in (1, 2)]
    family = OverlayFamily(DataScale.of(segs))
    calls = []
    original = Coupling.simulate

    def spy(self, angle, dt, state=None, **options):
        calls.append(self.params.shape[0])
        return original(self, angle, dt, state, **options)

    monkeypatch.setattr(Coupling, "simulate", spy)
    r = least_squares_fit(family, segs, family.initial())
    # each optimiser request is one call: a residual (1 set x 2 segments) or a whole
    # Jacobian (2 perturbed sets x 2 segments)
    assert r.core_calls == len(calls) == r.nfev + r.njev + 2  # + the final metrics, + the half-step bias
    assert calls.count(2 * 2) == r.njev and set(calls) == {2, 4}
    assert r.evaluations == r.nfev + 2 * r.njev + 2


def test_metrics_lag1_of_a_smooth_residual():
    seg, *_ = _kv_data(noise=1.0)
    prediction = seg.torque_nm + 5.0 * np.sin(np.arange(seg.n) / 50.0)  # slowly varying misfit
    m = metrics([seg], [prediction])
    assert m.residual_lag1 > 0.99
    assert m.rmse_nm == pytest.approx(5.0 / np.sqrt(2), rel=0.05)


def test_non_convergence_is_reported_not_hidden():
    seg, *_ = _kv_data(noise=1.0)
    family = OverlayFamily(DataScale.of([seg]))
    r = least_squares_fit(family, [seg], family.initial() * 50, max_nfev=2)
    assert not r.converged
    assert "maximum number of function evaluations" in r.message


def test_every_zerodim20_candidate_is_a_coupling_the_core_accepts():
    """The tables are parametrised so that no candidate the optimiser may propose inside the
    bounds makes a spring or dashpot force fall (without it 6 of 8 realistic data sets failed)."""
    from droptower.identify.families import ZeroDim20
    from droptower.identify.fit import clip_to_bounds

    family = ZeroDim20(DataScale(0.02, 0.02, 100.0, 5000.0, 1.0, 10.0))
    six = np.array([3000.0, 1500.0, 0.2, 2500.0, 5e4, 0.004])
    start = family.from_zerodim6(six)
    ks, cs = family.tables(start)  # the six-parameter model exactly
    assert np.allclose(ks, 2500.0 + 5e4 * np.abs(family.deformation_rad)) and np.allclose(cs, 10.0)
    rng = np.random.default_rng(0)
    lo, hi = np.array([p.z_bounds() for p in family.parameters]).T
    for _ in range(200):
        z = rng.uniform(lo, hi)
        family.coupling(clip_to_bounds(family.parameters, [p.to_value(v) for p, v in zip(family.parameters, z)]))
