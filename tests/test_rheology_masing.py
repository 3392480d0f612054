"""Prandtl (Jenkins) and Masing elements against closed forms (Heine & Plagemann 2014, docs/theory.md#elastoslide, #masing).

Coulomb sliders are rate independent and updated by return mapping, so at the samples the
model is exact for any time step: these tests use round-off tolerances.
"""
from __future__ import annotations

import numpy as np
import pytest

from test_rheology_support import sine, single, trapezoid_work

K_R, R_MAX, ALPHA, N = 300.0, 3.0, 3.0, 7  # seed003_masing preset values: N*m/rad, N*m, -, -


def _yields():
    """Heine & Plagemann 2014, eq. 4: R_i = R exp(alpha (eta_i - 1)), eta_i = (i - 1)/(n - 1), i = 1..n."""
    eta = (np.arange(1, N + 1) - 1) / (N - 1)
    return R_MAX * np.exp(ALPHA * (eta - 1))


def backbone(x):
    """Virgin curve of the bank: sum of min(k_R |x|, R_i), odd in x."""
    x = np.asarray(x, float)
    return np.sign(x) * np.minimum(K_R * np.abs(x)[..., None], _yields()).sum(-1)


def _masing(**extra):
    return single({"kind": "masing", "n": N, "stiffness": K_R, "max_yield_torque": R_MAX, "alpha": ALPHA, **extra})


def _path(turning_points, per_leg=400):
    """Piecewise-linear history through the turning points (each one a sample), from 0."""
    legs = [np.linspace(a, b, per_leg + 1)[1:] for a, b in zip([0.0] + turning_points[:-1], turning_points)]
    return np.concatenate(legs)


def test_masing_rule_with_memory():
    """Masing's rule: after a reversal at (x_r, F_r) the branch is F_r -/+ 2 F_bb(|x - x_r|/2)
    (the elastoslide paper, eq. 26; docs/theory.md#masing-rule), with F_bb the virgin curve; and the memory rule: when a
    branch reaches the previous reversal point, the inner loop closes and the curve continues
    on the branch it left (return-point memory of the Iwan bank).

    Turning points in units of the largest yield angle u = R/k_R: 0 -> 2 -> -1.6 -> 1.2 ->
    -0.8 -> 1.6 (the last leg passes the reversal at 1.2 and continues on the branch from
    -1.6). Expected values are chained from the rule alone, never from the simulation.
    """
    u = R_MAX / K_R
    a1, a2, a3, a4, a5 = 2.0 * u, -1.6 * u, 1.2 * u, -0.8 * u, 1.6 * u
    x = _path([a1, a2, a3, a4, a5])
    torque = _masing().respond(x, 1e-3)

    f1 = backbone(a1)
    f2 = f1 - 2 * backbone((a1 - a2) / 2)
    f3 = f2 + 2 * backbone((a3 - a2) / 2)
    f4 = f3 - 2 * backbone((a3 - a4) / 2)
    legs = np.split(np.arange(x.size), 5)
    expected = np.empty_like(x)
    expected[legs[0]] = backbone(x[legs[0]])
    expected[legs[1]] = f1 - 2 * backbone((a1 - x[legs[1]]) / 2)
    expected[legs[2]] = f2 + 2 * backbone((x[legs[2]] - a2) / 2)
    expected[legs[3]] = f3 - 2 * backbone((a3 - x[legs[3]]) / 2)
    xl = x[legs[4]]
    expected[legs[4]] = np.where(xl <= a3, f4 + 2 * backbone((xl - a4) / 2),   # inner branch
                                 f2 + 2 * backbone((xl - a2) / 2))            # memory: back on the a2 branch
    assert np.max(np.abs(torque - expected)) < 1e-10 * np.max(np.abs(expected))
    # the rule is not trivially met: the inner loop's branches differ from the outer ones
    assert np.max(np.abs(expected[legs[3]] - (f1 - 2 * backbone((a1 - x[legs[3]]) / 2)))) > 0.1 * R_MAX


def test_masing_rule_is_independent_of_time_step():
    """Rate independence: the same path sampled with any time step gives the same torques."""
    x = _path([0.02, -0.015, 0.01])
    coupling = _masing()
    assert np.allclose(coupling.respond(x, 1e-6), coupling.respond(x, 10.0), rtol=0, atol=1e-12)


K_P, F_P, A_P = 1000.0, 5.0, 2e-2  # Prandtl element: N*m/rad, N*m; amplitude 4 yield angles


def _prandtl_cycle(spc=4000):
    t, x, dt = sine(A_P, 1.0, spc, 2.25)
    torque = single({"kind": "prandtl", "stiffness": K_P, "yield_torque": F_P}).respond(x, dt)
    return t, x, torque, spc


def test_prandtl_full_slip_parallelogram():
    """In full slip (A > f/k) the loop of a Jenkins element is the parallelogram through
    (A, f), (A - 2f/k, -f), (-A, -f), (-A + 2f/k, f): at every sample of the steady cycle the
    torque is f - k (A - x) clipped to [-f, f] going down, -f + k (x + A) clipped going up."""
    t, x, torque, spc = _prandtl_cycle()
    s = slice(int(1.25 * spc), None)  # from the first peak on: steady
    going_down = np.gradient(x)[s] < 0
    expected = np.where(going_down, np.clip(F_P - K_P * (A_P - x[s]), -F_P, F_P),
                        np.clip(-F_P + K_P * (x[s] + A_P), -F_P, F_P))
    assert np.max(np.abs(torque[s] - expected)) < 1e-10 * F_P


def test_prandtl_loop_area():
    """Loop area 4 f (A - f/k) by the trapezoidal rule over one steady cycle. The trapezoids
    cut the two corners where sliding starts: each costs at most k dx^2 / 8, dx the largest
    step; that bound is the tolerance."""
    t, x, torque, spc = _prandtl_cycle()
    work = trapezoid_work(x, torque)
    loop = work[-1] - work[-spc - 1]
    dx = np.max(np.abs(np.diff(x)))
    assert abs(loop - 4 * F_P * (A_P - F_P / K_P)) <= 2 * K_P * dx ** 2 / 8 + 1e-12


@pytest.mark.parametrize("amplitude_yields", [1.2, 2.0, 4.0, 20.0])
def test_prandtl_describing_function(amplitude_yields):
    """First harmonic of full slip, K' and K'' of a Jenkins element at amplitude A > f/k.

    Derivation (x = A cos(theta), half-wave symmetric): from the reversal at theta = 0 the
    element unloads elastically, T = f - kA (1 - cos theta), until T = -f at theta*, where
    cos(theta*) = 1 - 2f/(kA); then it slides at T = -f until theta = pi. Projecting,
      K'  = (2/(pi A)) int_0^pi T cos(theta) d theta = (k/pi) (theta* - sin(2 theta*)/2),
      K'' = -(2/(pi A)) int_0^pi T sin(theta) d theta = (4 f/(pi A)) (1 - f/(kA)),
    so pi K'' A^2 = 4 f (A - f/k), the loop area, and K' -> k as A -> f/k.

    Numerical projection over a sampled cycle (4096 samples) errs by O(1/N^2) at the two
    corners: rtol 1e-5.
    """
    amplitude = amplitude_yields * F_P / K_P
    spc = 4096
    t, x, dt = sine(amplitude, 1.0, spc, 2.0)
    torque = single({"kind": "prandtl", "stiffness": K_P, "yield_torque": F_P}).respond(x, dt)
    n = spc
    w = 2 * np.pi * t[-n:]
    k_storage = 2 * np.mean(torque[-n:] * np.sin(w)) / amplitude
    k_loss = 2 * np.mean(torque[-n:] * np.cos(w)) / amplitude
    theta = np.arccos(1 - 2 * F_P / (K_P * amplitude))
    assert k_storage == pytest.approx(K_P / np.pi * (theta - np.sin(2 * theta) / 2), rel=1e-5)
    assert k_loss == pytest.approx(4 * F_P / (np.pi * amplitude) * (1 - F_P / (K_P * amplitude)), rel=1e-5)


def test_prandtl_below_yield_is_elastic():
    """Below the yield angle the Jenkins element is a linear spring: K' = k, K'' = 0."""
    amplitude = 0.9 * F_P / K_P
    t, x, dt = sine(amplitude, 1.0, 1000, 2.0)
    torque = single({"kind": "prandtl", "stiffness": K_P, "yield_torque": F_P}).respond(x, dt)
    assert np.max(np.abs(torque - K_P * x)) < 1e-12 * F_P  # the elongation sums the steps: round-off
