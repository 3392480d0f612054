"""The ``large_strain_network`` element against its closed forms (docs/theory.md#large-strain-network):
the stiffening spring, the scragging damage's limit, the stiffening network's loop tips and the
energy a closed cycle dissipates."""
from __future__ import annotations

import numpy as np
import pytest

from droptower.rheology import Coupling
from droptower.rheology.elements import LargeStrainNetwork

H = 1e-3  # s: the element is rate-independent; any step


def _coupling(**fields) -> Coupling:
    return Coupling([LargeStrainNetwork(kind="large_strain_network", **fields)])


def _cycles(amplitude: float, cycles: int, per_cycle: int = 400) -> np.ndarray:
    t = np.arange(1, cycles * per_cycle + 1) / per_cycle
    return amplitude * np.sin(2 * np.pi * t)


def test_without_damage_and_network_it_is_the_stiffening_spring():
    x = _cycles(0.3, 2)
    torque = _coupling(stiffness=2e3, gain=5e3, exponent=2.5).respond(x, H)
    assert np.allclose(torque, (2e3 + 5e3 * np.abs(x) ** 2.5) * x, rtol=1e-12, atol=0)


def test_scragging_reaches_its_limit_set_by_the_largest_angle():
    """After a travel of many L at one amplitude A the spring is softened by D_inf(A) =
    D_max (1 - exp(-(A/x_D)^r)); a smaller amplitude afterwards keeps it (no recovery)."""
    k, d_max, x_d, r, travel = 1e3, 0.6, 0.2, 1.5, 0.05
    c = _coupling(stiffness=k, damage=d_max, damage_angle=x_d, damage_exponent=r, damage_travel=travel)
    amplitude = 0.3
    x = np.concatenate([_cycles(amplitude, 6), _cycles(0.1, 2)])  # travel 7.2 = 144 L, then smaller loops
    torque = c.respond(x, H)
    d_inf = d_max * (1 - np.exp(-(amplitude / x_d) ** r))
    tip = 5 * 400 + np.argmax(x[5 * 400: 6 * 400])  # the last cycle's tip
    assert torque[tip] / x[tip] == pytest.approx(k * (1 - d_inf), rel=1e-9)
    small = 6 * 400 + np.argmax(x[6 * 400:])
    assert torque[small] / x[small] == pytest.approx(k * (1 - d_inf), rel=1e-9)


def test_the_network_loop_tips_and_its_loss():
    """A symmetric cycle beyond every slip: at the tip every spring is at its slip s_i, so the
    torque is k_n ((1 + g A^2) sum s_i + g A sum s_i^2) (k_n = network_stiffness / n); the energy
    of a steady cycle is all dissipated (stored energy back to its start), and equals the loop's area."""
    n, kf, slip, spread, g, amplitude = 8, 4e3, 0.05, 1.5, 20.0, 0.2
    element = LargeStrainNetwork(kind="large_strain_network", network_stiffness=kf, slip=slip, spread=spread,
                                 friction_gain=g, n=n)
    s = element.slips()
    x = _cycles(amplitude, 3)
    response = Coupling([element]).simulate(x, H)
    tip = 2 * 400 + np.argmax(x[2 * 400:])
    expected = kf / n * ((1 + g * amplitude ** 2) * s.sum() + g * amplitude * (s ** 2).sum())
    assert response.torque_nm[tip] == pytest.approx(expected, rel=1e-9)
    one = slice(399, 800)  # the second cycle (from its first sample's predecessor): steady
    area = float(np.sum(0.5 * (response.torque_nm[one][1:] + response.torque_nm[one][:-1]) * np.diff(x[one])))
    dissipated = response.dissipated_energy_j[799] - response.dissipated_energy_j[399]
    assert area > 0 and dissipated == pytest.approx(area, rel=1e-9)
    assert response.stored_energy_j[799] == pytest.approx(response.stored_energy_j[399], rel=1e-9)


def test_every_gain_may_vanish():
    """The element with every gain at 0 carries nothing; the spec refuses a damage of 1 or more."""
    assert np.all(_coupling().respond(_cycles(0.2, 1), H) == 0.0)
    with pytest.raises(ValueError, match="damage"):
        LargeStrainNetwork(kind="large_strain_network", damage=1.0)


def test_each_side_scrags_on_its_own_travel():
    """With ``damage_sides`` the positive and the negative side keep their own D and x_max (Gallardo
    et al. 2023's Mullins strain of each side): after many cycles from 0 to A only, the spring
    is k (1 - D_inf(A)) on that side and, at the first step below 0, k softened only by that
    step's own travel; shared, it is softened on both alike."""
    k, d_max, x_d, r, travel, amplitude = 1e3, 0.6, 0.2, 1.5, 0.05, 0.3
    x = np.concatenate([amplitude * 0.5 * (1 - np.cos(2 * np.pi * np.arange(1, 2401) / 400)), [-1e-3]])
    d_inf = d_max * (1 - np.exp(-(amplitude / x_d) ** r))
    tip = 5 * 400 + 200
    fresh = d_max * (1 - np.exp(-(1e-3 / x_d) ** r)) * (1 - np.exp(-1e-3 / travel))  # the step's own scragging
    for sides, below in ((True, 1 - fresh), (False, 1 - d_inf)):
        torque = _coupling(stiffness=k, damage=d_max, damage_angle=x_d, damage_exponent=r, damage_travel=travel,
                           damage_sides=sides).respond(x, H)
        assert torque[tip] / x[tip] == pytest.approx(k * (1 - d_inf), rel=1e-9)
        assert torque[-1] / x[-1] == pytest.approx(k * below, rel=1e-12)


def test_the_spring_softens_with_the_travel():
    """``travel_softening`` f: the spring's linear stiffness is k exp(-f c^p) at every sample, c the
    travel sum |dx| from rest (Gallardo et al. 2023's k_M), going on at a fixed amplitude."""
    k, f, p = 2e3, 0.4, 0.6
    x = _cycles(0.3, 3)
    torque = _coupling(stiffness=k, travel_softening=f, travel_exponent=p).respond(x, H)
    travel = np.cumsum(np.abs(np.diff(np.concatenate([[0.0], x]))))
    assert np.allclose(torque, k * np.exp(-f * travel ** p) * x, rtol=1e-12, atol=0)
    assert torque[3 * 400 - 300] < torque[400 - 300]  # the third cycle's tip below the first's


def test_the_slips_widen_with_the_last_reversal():
    """``slip_hardening`` h: beyond every slip the network's torque is k_n sum s_i (1 + h r), r the |x|
    at the motion's last reversal (0 before the first): Gallardo et al. 2023's temporary hardening
    of the friction, set by the excursion there."""
    n, kf, slip, h = 8, 4e3, 0.02, 3.0
    element = LargeStrainNetwork(kind="large_strain_network", network_stiffness=kf, slip=slip, slip_hardening=h, n=n)
    s = element.slips()
    x = np.concatenate([np.linspace(0, 0.2, 201)[1:], np.linspace(0.2, -0.1, 301)[1:], np.linspace(-0.1, 0.3, 401)[1:]])
    torque = Coupling([element]).respond(x, H)
    assert torque[199] == pytest.approx(kf / n * s.sum(), rel=1e-12)  # first loading: no reversal yet
    assert torque[499] == pytest.approx(-kf / n * s.sum() * (1 + h * 0.2), rel=1e-12)  # reversed at 0.2
    assert torque[-1] == pytest.approx(kf / n * s.sum() * (1 + h * 0.1), rel=1e-12)  # reversed at -0.1
