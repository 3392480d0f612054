"""History effects: Mullins first cycles (the zero-dimensional model paper, eq. 3) and the constricted (waisted)
Masing loop (Heine & Plagemann 2014, eq. 6)."""
from __future__ import annotations

import numpy as np
import pytest

from test_rheology_support import single

K_SLOW, K_FAST, TAU = 1000.0, 1500.0, 0.5  # N*m/rad, N*m/rad, s
F_HZ, AMP, MEAN, SPC, CYCLES = 2.0, 0.005, 0.02, 1000, 12  # Hz, rad, rad, samples/cycle, cycles


def _preloaded_sine(coupling):
    """Step of the mean angle to MEAN within the first sample, then MEAN + AMP sin(2 pi f t).
    Returns the peak-to-peak secant stiffness (T_max - T_min)/(x_max - x_min) per cycle."""
    dt = 1.0 / (F_HZ * SPC)
    t = np.arange(1, CYCLES * SPC + 1) * dt
    x = MEAN + AMP * np.sin(2 * np.pi * F_HZ * t)
    torque = coupling.respond(x, dt)
    tc, xc = torque.reshape(CYCLES, SPC), x.reshape(CYCLES, SPC)
    return (tc.max(1) - tc.min(1)) / (xc.max(1) - xc.min(1))


def _mullins(fast=K_FAST, **slow):
    slow = slow or {"slow_stiffness": K_SLOW}
    return single({"kind": "mullins", "tau": TAU, "fast_stiffness": fast, **slow})


def test_first_cycles_stiffer_than_steady_cycles():
    """The zero-dimensional model paper, eq. 3, T = k1 LP(x) + k2 (x - LP(x)): after a step of the mean angle the fast
    stiffness carries the step and relaxes to the slow one over tau, so the first cycle of a
    preloaded sine has a higher peak-to-peak secant stiffness than the late ones (the zero-dimensional model paper,
    Fig. 7). Late cycles (after 11 tau) are the steady linear response, whose secant is
    |K*| = |k1 + (k2 - k1) i w tau / (1 + i w tau)| (exact for a sine, up to the sampling of
    the peaks: rtol 1e-4). The first cycle: the decaying step torque (k2 - k1) MEAN e^(-t/tau)
    falls by about 3 N*m between the peak and the trough: > 15 % stiffer."""
    secant = _preloaded_sine(_mullins())
    iwt = 1j * 2 * np.pi * F_HZ * TAU
    steady = abs(K_SLOW + (K_FAST - K_SLOW) * iwt / (1 + iwt))
    assert secant[-1] == pytest.approx(steady, rel=1e-4)
    assert secant[0] > 1.15 * secant[-1]
    assert np.all(np.diff(secant[:6]) < 0)  # and the excess decays cycle by cycle


def test_no_mullins_without_fast_part():
    """Control: with fast = slow stiffness the element is a spring, every cycle the same."""
    secant = _preloaded_sine(_mullins(fast=K_SLOW))
    assert np.allclose(secant, K_SLOW, rtol=1e-9)


def test_first_cycles_stiffer_with_slow_curve():
    """The same with the slow part as a static curve (the zero-dimensional model paper's k1(theta) lookup)."""
    curve = {"angle": [-0.1, 0.0, 0.01, 0.1], "torque": [-120.0, 0.0, 10.0, 120.0]}
    secant = _preloaded_sine(_mullins(slow_curve={"kind": "spring_table", **curve}))
    assert secant[0] > 1.15 * secant[-1]


K_M, R_M, ALPHA_M, N_M = 300.0, 3.0, 3.0, 7          # masing bank, seed003_masing values
P_C, K_C = 400.0, 0.1                                 # constriction: 1/rad, floor
A_M = 0.02                                            # rad, twice the largest yield angle


def _steady_loop(coupling, spc=2000):
    """(x, torque) of the steady cycle of a sine, from the first peak to the next."""
    dt = 1.0 / spc
    t = np.arange(1, int(2.25 * spc) + 1) * dt
    x = A_M * np.sin(2 * np.pi * t)
    torque = coupling.respond(x, dt)
    s = slice(int(1.25 * spc) - 1, None)
    return x[s], torque[s]


def _width(x, torque, at):
    """Loop width T_up(at) - T_down(at): the branches going up and down, interpolated."""
    down = np.gradient(x) < 0
    xd, td = x[down][::-1], torque[down][::-1]
    xu, tu = x[~down], torque[~down]
    order = np.argsort(xu)
    return np.interp(at, xu[order], tu[order]) - np.interp(at, xd, td)


def _masing(constriction=None):
    el = {"kind": "masing", "n": N_M, "stiffness": K_M, "max_yield_torque": R_M, "alpha": ALPHA_M}
    if constriction:
        el["constriction"] = {"p": P_C, "k": K_C}
    return single(el)


def test_constriction_scales_the_bank_by_s_of_x():
    """Heine & Plagemann 2014, eq. 6: the Prandtl sum is multiplied by S(x) = (|tanh(P x)| + K)/(1 + K); the
    bank's own state does not depend on S, so torque_constricted = S(x) torque_plain at every
    sample (rtol 1e-12)."""
    x, plain = _steady_loop(_masing())
    _, constricted = _steady_loop(_masing(constriction=True))
    s = (np.abs(np.tanh(P_C * x)) + K_C) / (1 + K_C)
    assert np.allclose(constricted, s * plain, rtol=1e-12, atol=1e-12 * R_M)


def test_constriction_waists_the_loop():
    """The loop's width at x = 0 relative to its width at 0.6 A is smaller with the
    constriction: by the factor S(0)/S(0.6 A) = K/(tanh(0.6 P A) + K) = 0.092 here. Checked
    in the loop (interpolated branches; the interpolation error is the same with and without,
    rtol 1e-3) and, as a property, < 0.5 of the plain ratio."""
    x, plain = _steady_loop(_masing())
    _, constricted = _steady_loop(_masing(constriction=True))
    at = np.array([0.0, 0.6 * A_M])
    w_plain, w_constricted = _width(x, plain, at), _width(x, constricted, at)
    assert np.all(w_plain > 0) and np.all(w_constricted > 0)
    ratio_plain = w_plain[0] / w_plain[1]
    ratio_constricted = w_constricted[0] / w_constricted[1]
    assert ratio_constricted < 0.5 * ratio_plain
    assert ratio_constricted / ratio_plain == pytest.approx(K_C / (np.tanh(0.6 * P_C * A_M) + K_C), rel=1e-3)
