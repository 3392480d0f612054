"""Free flight between contacts (droptower/rig/flight.py) against pymunk stepping the whole record,
and its clearance test against the exact motion."""
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

from droptower.rheology import load_coupling
from droptower.rheology.loader import parse_coupling
from droptower.rig.config import load_rig
from droptower.rig.flight import MARGIN_M, clear_of
from droptower.rig.preload import pretwist
from droptower.rig.simulate import DropTest, _run_batch

K_LIN = 14000.0  # N*m/rad, docs/theory.md#impact


@pytest.fixture(scope="module")
def rig():
    return load_rig("rapp2022")


@pytest.fixture(scope="module")
def couplings():
    linear = parse_coupling({"name": "linear", "element": [{"kind": "spring", "stiffness": K_LIN},
                                                          {"kind": "dashpot", "damping": 40.0}]})
    return {"linear": linear, "rapp2022_nr60": load_coupling("rapp2022_nr60")}


def _both(rig, coupling, tests, duration_s):
    def twist():  # each run advances its coupling state in place
        return pretwist(coupling, np.array([t.preload_nm for t in tests]), rig.simulation.preload_ramp_s,
                        rig.simulation.preload_hold_s)

    return (_run_batch(rig, coupling, tests, duration_s, twist()),
            _run_batch(rig, coupling, tests, duration_s, twist(), fly_between_contacts=False))


test_case = st.builds(DropTest, st.sampled_from([0.1557, 0.359, 0.5233]), st.sampled_from([1.0, 2.0]),
                      st.floats(0.05, 6.0), st.sampled_from([0.0, 500.0, 1000.0]))


@settings(max_examples=6, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow],
          phases=[Phase.explicit, Phase.generate])  # an example takes seconds: no shrinking
@given(tests=st.lists(test_case, min_size=1, max_size=10), name=st.sampled_from(["linear", "rapp2022_nr60"]))
def test_flight_between_contacts_equals_pymunk_all_along(rig, couplings, tests, name):
    """Random batches (few: the property path; many: the batch API), 60 ms records with second
    contacts and drop masses resting on the lever: the same contacts, step for step, and the same
    records up to rounding (the two integrate the same steps; pymunk's coordinates sit up to tens of
    metres from the origin, so they round in the last bits differently)."""
    flown, stepped = _both(rig, couplings[name], tests, 0.06)
    for a, b in zip(flown, stepped):
        assert [(c.start_s, c.steps) for c in a.contacts] == [(c.start_s, c.steps) for c in b.contacts]
        for x, y in ((a.angle_rad, b.angle_rad), (a.coupling_torque_nm, b.coupling_torque_nm),
                     (a.drop_mass_m, b.drop_mass_m), (a.contact_impulse_ns, b.contact_impulse_ns)):
            np.testing.assert_allclose(x, y, rtol=0, atol=1e-7 * np.abs(y).max())
        for key, energy in b.energy_j.items():
            scale = b.test.drop_mass_kg * rig.gravity_m_per_s2 * b.test.drop_height_m
            np.testing.assert_allclose(a.energy_j[key], energy, rtol=0, atol=1e-7 * scale, err_msg=key)
        assert a.warnings == b.warnings
        assert a.energy_balance_error < 0.01


@settings(max_examples=400, deadline=None, derandomize=True)
@given(phi=st.floats(-0.3, 0.3), w=st.floats(-40.0, 40.0), alpha=st.floats(-5e4, 5e4),
       gap=st.floats(-1e-3, 2e-2), v=st.floats(-12.0, 12.0), samples=st.integers(1, 8))
def test_clear_means_no_closer_than_the_margin_over_the_horizon(phi, w, alpha, gap, v, samples):
    """Where ``clear_of`` says clear, the exact motion over the horizon (lever at constant angular
    acceleration, drop mass in free fall) keeps the striker more than the margin from the lever."""
    L, r, g, h = 0.4, 0.01, 9.81, 1.0 / 76800.0
    y = (gap + r - L * math.sin(phi)) / math.cos(phi)  # the striker's centre that many m from the line
    horizon = 2 * samples * h
    if not clear_of(phi, w, alpha, y, v, L, r, g, horizon):
        return
    t = np.linspace(0.0, horizon, 200)
    angle = phi + w * t + 0.5 * alpha * t ** 2
    height = y + v * t - 0.5 * g * t ** 2
    assert np.min(L * np.sin(angle) + height * np.cos(angle) - r) > MARGIN_M


def test_not_clear_when_touching_or_closing_fast():
    L, r, g = 0.4, 0.01, 9.81
    assert not clear_of(0.0, 0.0, 0.0, r, 0.0, L, r, g, 1e-4)           # resting on the lever
    assert not clear_of(0.0, 0.0, 0.0, r + 2e-3, -10.0, L, r, g, 2e-4)  # 2 mm away at 10 m/s
    assert clear_of(0.0, 0.0, 0.0, r + 2e-3, 1.0, L, r, g, 2e-4)        # 2 mm away, rising
