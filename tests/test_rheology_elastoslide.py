"""The distributed rate-dependent elastoslide element against the elastoslide paper's closed forms (docs/theory.md#elastoslide).

- steady sliding: a slider of yield force f* sliding at a constant rate v carries
  f* (v / v_r)^(1/p) (the elastoslide paper, eq. 12/13 at dx0/dt = v);
- the Coulomb limit p -> infinity: loop energy W_D of the Masing closed form;
- the initial loading curve eq. 24 from the discretised exponential distribution (eq. 25).
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

from test_rheology_support import sine, single, trapezoid_work


def _bank(k, k0, v_r, p, yields, weights):
    return single({"kind": "elastoslide", "k": k, "k0": k0, "v_r": v_r, "p": p,
                   "distribution": {"yield_torque": list(yields), "weight": list(weights)}})


def _steady_sliding(p, rate_ratio):
    """Ramp at constant rate v = rate_ratio * v_r far into steady sliding through a bank of
    five elements (distribution) and k0; return (model torque at the end, closed form)."""
    k, k0, v_r = 2.0e4, 300.0, 0.5
    yields = np.array([0.5, 2.0, 5.0, 20.0, 60.0])       # N*m
    weights = np.array([0.1, 0.3, 0.2, 0.3, 0.1])
    v = rate_ratio * v_r
    # steady elongation of the stiffest-yield element; the transient after it starts to slide
    # decays like exp(-p x / e_ss), so 40 e_ss of travel leaves nothing of it
    e_ss = yields.max() / k * rate_ratio ** (1.0 / p)
    n = 4000
    x = np.arange(1, n + 1) * (40 * e_ss / n)
    torque = _bank(k, k0, v_r, p, yields, weights).respond(x, (x[1] - x[0]) / v)
    expected = np.sum(weights * yields) * rate_ratio ** (1.0 / p) + k0 * x[-1]
    return torque[-1], expected


@pytest.mark.parametrize("p", [1, 3, 7, 31, 33, 101])
@pytest.mark.parametrize("rate_ratio", [1e-3, 1.0, 1e3])
def test_steady_sliding_force(p, rate_ratio):
    """Sum of w_i f*_i (v/v_r)^(1/p) + k0 x. Backward Euler's fixed point of steady sliding
    is the continuous one exactly, so only Newton's tolerance (1e-11) and round-off remain:
    rtol 1e-8."""
    torque, expected = _steady_sliding(p, rate_ratio)
    assert torque == pytest.approx(expected, rel=1e-8)


@pytest.mark.parametrize("p", [1, 3, 7, 31, 33, 51, 101])
def test_single_element_equals_backward_euler_reference(p):
    """One elastoslide element under a sine of 4 yield angles, against a backward-Euler step
    written here and solved by bracketing (brentq): e1 + h v_r (k e1/f*)^p = e0 + dx.
    Both solve the same implicit equation, so they agree to the root tolerance: 1e-10 f*.
    (Exponents above 32 once took a wrong branch-free power in the kernel's fast Newton pass.)"""
    k, f_star, amplitude, spc = 1000.0, 1.0, 4e-3, 400
    v_r = 0.5 * 2 * np.pi * amplitude
    t, x, dt = sine(amplitude, 1.0, spc, 2.25)
    torque = _bank(k, 0.0, v_r, p, [f_star], [1.0]).respond(x, dt)
    e, x0, reference = 0.0, 0.0, []
    for x1 in x:
        b = e + x1 - x0
        e = brentq(lambda e1: e1 + dt * v_r * np.sign(e1) * abs(k * e1 / f_star) ** p - b,
                   min(0.0, b), max(0.0, b), xtol=1e-16, rtol=1e-15) if b else 0.0
        reference.append(k * e)
        x0 = x1
    assert np.max(np.abs(torque - np.array(reference))) < 1e-10 * f_star


def test_large_step_with_large_exponent_is_finite():
    """One backward-Euler step of 0.1 rad onto an element with yield angle 5e-5 rad, p = 101:
    u + A u^p = B with B = 2000 has one root; compare with a bracketing solver. (A Newton start
    at u = B once overflowed u^p to inf and gave NaN.)"""
    k, f_star, v_r, p, h, dx = 2.0e4, 1.0, 1.0, 101, 1e-3, 0.1
    torque = _bank(k, 0.0, v_r, p, [f_star], [1.0]).respond(np.array([dx]), h)
    a, b = h * v_r * k / f_star, k * dx / f_star
    u = brentq(lambda u: u + a * u ** p - b if u < 50 else np.inf, 0.0, b, xtol=1e-15)
    assert torque[0] == pytest.approx(f_star * u, rel=1e-9)


def _masing_loop_energy_error(p, c_amplitude, n=128):
    """Relative error of the steady loop energy of the distributed model against the Masing
    closed form W_D = (4/phi0) [A (1 + e^-aA) - 2 (1 - e^-aA)/a], a = k phi0, at A = c/a.

    The frequency is set so that the peak rate is the same at every amplitude, v_pk = 1 rad/s,
    with v_r = v_pk / 2 (the mean of ln|sin|: sliding speeds average around v_r).
    """
    phi0, k = 0.02, 2.0e4
    a = k * phi0
    amplitude = c_amplitude / a
    spc = 4000
    coupling = single({"kind": "elastoslide", "phi0": phi0, "k": k, "k0": 0.0, "v_r": 0.5, "p": p, "n": n})
    t, x, dt = sine(amplitude, 1.0 / (2 * np.pi * amplitude), spc, 2.25)
    work = trapezoid_work(x, coupling.respond(x, dt))
    loop = work[-1] - work[-spc - 1]  # from the peak at 1.25 cycles to the peak at 2.25 cycles
    exact = (4 / phi0) * (amplitude * (1 + np.exp(-a * amplitude)) - 2 * (1 - np.exp(-a * amplitude)) / a)
    return loop / exact - 1.0


AMPLITUDES_A = [0.1, 0.3, 1.0, 2.0, 5.0]  # amplitude x a


@pytest.mark.parametrize("c_amplitude", AMPLITUDES_A)
def test_loop_energy_tends_to_masing_closed_form(c_amplitude, regression):
    """As p grows the elastoslide becomes a Coulomb (Jenkins) bank and its loop energy tends
    to the Masing closed form of docs/theory.md#elastoslide.

    At finite p the sliders relax near every reversal (their force falls like (v/v_r)^(1/p)
    as the rate goes to 0) and creep below yield, which widens the loop by O(ln(range of
    rates)/p): +2 % ... +6 % at p = 101, measured with a fine reference (exact Newton), and
    it shrinks like 1/p. So: within 2 % at p = 1001 at every amplitude 0.1/a ... 5/a (the
    brief's p = 51 or 101 are not large enough for 2 %: 10 % and 6 % at A = 0.1/a), within
    7 % at p = 101, and the error falls by more than 3x from p = 101 to p = 1001. The
    discretisation (n = 128 equal-probability bins) adds < 0.3 % (checked with the Coulomb
    Prandtl bank of the same bins).
    """
    err_101 = _masing_loop_energy_error(101, c_amplitude)
    err_1001 = _masing_loop_energy_error(1001, c_amplitude)
    assert abs(err_1001) < 0.02
    assert abs(err_101) < 0.07
    assert abs(err_1001) < abs(err_101) / 3
    # the measured errors themselves, stored (tests/regression.py): a deterministic computation,
    # reproducible to round-off far below 1e-6 of an error of >= 1e-3
    regression.check("loop_energy_error_p101", err_101, rel=1e-6)
    regression.check("loop_energy_error_p1001", err_1001, rel=1e-6)


# the elastoslide paper, Table 1, specimen without preload, in N and m
PHI0, K_LEAD, K0, V_R = 0.0068, 504510.0, 44440.0, 0.05


def _loading_curve_error(p, n, rate_ratio, steps=10000):
    """Max relative error of a monotone ramp at v = rate_ratio * v_r against eq. 24 with the
    distribution constant of the rate: each steady slider carries f* c, c = (v/v_r)^(1/p),
    which turns eq. 24 into F = (c/phi0)(1 - exp(-k phi0 x / c)) + k0 x. Ramp to 5/(k phi0)."""
    coupling = single({"kind": "elastoslide", "phi0": PHI0, "k": K_LEAD, "k0": K0, "v_r": V_R, "p": p, "n": n})
    x_max = 5.0 / (K_LEAD * PHI0)
    x = np.arange(1, steps + 1) * (x_max / steps)
    torque = coupling.respond(x, (x_max / steps) / (rate_ratio * V_R))
    c = rate_ratio ** (1.0 / p)
    eq24 = (c / PHI0) * (1 - np.exp(-K_LEAD * PHI0 * x / c)) + K0 * x
    return np.max(np.abs(torque / eq24 - 1.0))


@pytest.mark.parametrize("rate_ratio", [1.0, 1e-3])
def test_initial_loading_curve_eq24_seed001_specimen(rate_ratio, regression):
    """The elastoslide paper, eq. 24 from the discretised model of Table 1's specimen (n = 32, p = 7).

    At v = v_r a sliding element carries exactly f*, so eq. 24 holds as printed; a slow ramp
    (v << v_r) does not remove the rate effect, it scales every slider force by
    (v/v_r)^(1/p) (0.37 at v = v_r/1000): eq. 24 then holds with phi0 / (v/v_r)^(1/p).
    Tolerance 2 %: the p = 7 sliders leave yield along a smooth curve, not a corner; that
    rounds the curve by up to 1.4 % near x = 1/(k phi0), independent of n (measured 1.36 %
    ... 1.38 % for n = 32 ... 256).
    """
    error = _loading_curve_error(7, 32, rate_ratio)
    assert error < 0.02
    regression.check("max_relative_error", error, rel=1e-6)  # the measured 1.36 %, stored (deterministic)


def test_initial_loading_curve_converges_with_n():
    """With near-Coulomb sliders (p = 101, at v = v_r) the only error left is the
    discretisation of phi(f*) into n equal-probability bins: 0.8 % at n = 32, and it halves
    with each doubling of n (first order in 1/n: the element whose bin holds f* = k x is
    either fully stuck or fully slipping)."""
    errors = [_loading_curve_error(101, n, 1.0) for n in (32, 64, 128, 256)]
    assert errors[0] < 0.01
    assert all(e2 < 0.6 * e1 for e1, e2 in zip(errors, errors[1:]))
