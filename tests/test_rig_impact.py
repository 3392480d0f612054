"""Closed forms of the drop-tower impact and free decay (docs/theory.md#impact, #decay)."""
import numpy as np
import pytest

from droptower.sdof import damping_ratio
from droptower.rig.impact_law import (drop_mass_path, first_period, impact_velocities,
                                      lever_tip_path, linear_free_decay, second_impact_time)

L = 0.2
CASES = [(1.0, 0.1557), (2.0, 0.1557), (2.0, 0.359), (2.0, 0.5233)]


@pytest.mark.parametrize("m1, J", CASES)
@pytest.mark.parametrize("k", [0.0, 0.5, 1.0])
def test_impact_law_conserves_momentum_and_obeys_restitution(m1, J, k):
    h = np.array([0.005, 0.05, 1.0, 6.0])
    iv = impact_velocities(m1, J, L, h, k)
    m2 = J / L**2
    v1 = np.sqrt(2 * 9.81 * h)
    np.testing.assert_allclose(m1 * v1, m1 * iv.drop_mass_after_m_per_s + m2 * iv.lever_tip_after_m_per_s, rtol=1e-12)
    np.testing.assert_allclose(iv.lever_tip_after_m_per_s - iv.drop_mass_after_m_per_s, k * v1, rtol=1e-12, atol=1e-15)
    # kinetic energy lost in the contact, and the lever's share (E_imp = 1/2 J phi'^2 = 1/2 m2 v2'^2)
    ke_after = 0.5 * m1 * iv.drop_mass_after_m_per_s**2 + 0.5 * m2 * iv.lever_tip_after_m_per_s**2
    np.testing.assert_allclose(0.5 * m1 * v1**2 - ke_after, iv.restitution_loss_j, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(iv.impact_energy_j, 0.5 * m2 * iv.lever_tip_after_m_per_s**2, rtol=1e-12)
    np.testing.assert_allclose(iv.impulse_ns, m2 * iv.lever_tip_after_m_per_s, rtol=1e-12)


def test_paper_mass_choice_direction_of_rebound():
    """Rapp et al. 2022, Fig. 4: the lightest lever reverses the 1 kg mass; with 2 kg it barely moves on."""
    light = impact_velocities(1.0, 0.1557, L, 1.0, 0.5)
    heavy = impact_velocities(2.0, 0.1557, L, 1.0, 0.5)
    assert light.drop_mass_after_m_per_s < 0  # upwards
    assert 0 < heavy.drop_mass_after_m_per_s < 0.02 * heavy.impact_m_per_s


def test_linear_free_decay_solves_the_ode():
    c, d, J, rate0 = 14000.0, 15.0, 0.359, 5.0
    t = np.linspace(0, 0.1, 200001)
    phi, delta, omega = linear_free_decay(c, d, J, rate0, t)
    dt = t[1] - t[0]
    acc = np.gradient(np.gradient(phi, dt), dt)
    vel = np.gradient(phi, dt)
    residual = J * acc + d * vel + c * phi
    assert np.max(np.abs(residual[5:-5])) < 1e-4 * c * np.max(np.abs(phi))
    assert phi[0] == 0 and abs(vel[1] - rate0) < 1e-3 * rate0
    assert delta == pytest.approx(d / (2 * J)) and omega == pytest.approx(np.sqrt(c / J - delta**2))
    with pytest.raises(ValueError):
        linear_free_decay(1.0, 100.0, 0.1, 1.0, t)


def test_first_period_of_a_damped_sine():
    t = np.linspace(0, 0.2, 20001)
    phi = np.exp(-20 * t) * np.sin(2 * np.pi * 31.0 * t)
    assert first_period(t, phi) == pytest.approx(1 / 31.0, rel=1e-6)
    assert first_period(t[None, :].repeat(2, 0)[:, :100], phi[None, :100].repeat(2, 0)).shape == (2,)
    assert np.isnan(first_period(t, np.exp(-t)))  # no oscillation


def test_second_impact_time_finds_the_crossing():
    """A tip on a sine and a mass thrown up: the first time they meet again, against brentq."""
    from scipy.optimize import brentq

    t = np.linspace(0, 0.05, 5001)
    omega, amp, v_after = 2 * np.pi * 40, 2e-3, -0.05

    def gap(s):
        return lever_tip_path(amp / L * np.sin(omega * s), L) - drop_mass_path(v_after, s)

    expected = brentq(gap, 0.3 / 40, 0.999 / 40)
    found = second_impact_time(t, drop_mass_path(v_after, t), lever_tip_path(amp / L * np.sin(omega * t), L))
    assert found == pytest.approx(expected, abs=2e-6)
    assert np.isnan(second_impact_time(t, drop_mass_path(v_after, t), lever_tip_path(amp / L * np.sin(omega * t), L),
                                       horizon_s=0.5 * expected))
    # rows: one meets, one (thrown up fast) does not
    x1 = np.stack([drop_mass_path(v_after, t), drop_mass_path(-2.0, t)])
    out = second_impact_time(t, x1, lever_tip_path(amp / L * np.sin(omega * t), L)[None, :].repeat(2, 0))
    assert np.isfinite(out[0]) and np.isnan(out[1])


def test_damping_ratio_eq16():
    r = np.log(4.0) / (4 * np.pi)  # d_ratio = 1.5 exactly
    assert damping_ratio(r * 200.0, 200.0) == pytest.approx(1.5)
