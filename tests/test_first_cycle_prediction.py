"""The first-cycle reading predicted from a coupling's steady loops
(:func:`droptower.compare.first_cycle.loop_span_damping_ratio`, docs/theory.md#first-cycle): on a
linear coupling the loops do not change with the amplitude and the energy balance has a closed
form; the preset's check against its drop-tower readings is in tests/test_nr60_calibration.py."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from droptower.compare.first_cycle import loop_span_damping_ratio
from droptower.errors import DroptowerError
from droptower.rheology import parse_coupling


def _spring_and_maxwell(spring: float, branch: float, relaxation_s: float):
    return parse_coupling({"name": "linear", "element": [
        {"kind": "spring", "stiffness": spring},
        {"kind": "maxwell", "stiffness": branch, "damping": branch * relaxation_s}]})


@pytest.mark.slow
@settings(max_examples=12, derandomize=True, deadline=None)
@given(st.floats(1e3, 1e5), st.floats(0.01, 1.0), st.floats(1e-4, 1.0), st.floats(5.0, 100.0), st.floats(1e-3, 0.1))
def test_linear_coupling_decays_by_its_loss_factor(spring, branch_share, relaxation_s, frequency_hz, amplitude_rad):
    """Spring + Maxwell branch: K' and K'' do not depend on the amplitude, so dE/dn = -2 pi eta E,
    E_1 = E_0 e^(-2 pi eta) and d = 1/2 (e^(2 pi eta) - 1), eta the loss factor at the frequency
    (Maxwell: K' = k (w tau)^2 / (1 + (w tau)^2), K'' = k w tau / (1 + (w tau)^2)); the branch at
    most as stiff as the spring keeps eta <= 1/3, d <= 3.6."""
    branch = branch_share * spring
    wt = 2 * np.pi * frequency_hz * relaxation_s
    eta = branch * wt / (1 + wt ** 2) / (spring + branch * wt ** 2 / (1 + wt ** 2))
    d = loop_span_damping_ratio(_spring_and_maxwell(spring, branch, relaxation_s), [amplitude_rad], frequency_hz)
    np.testing.assert_allclose(d, 0.5 * np.expm1(2 * np.pi * eta), rtol=1e-3)


def test_bad_input_is_one_clear_error():
    coupling = _spring_and_maxwell(1e4, 1e3, 0.01)
    with pytest.raises(DroptowerError, match="positive and finite"):
        loop_span_damping_ratio(coupling, [-0.01], 30.0)
    with pytest.raises(DroptowerError, match="d above 12"):  # a cycle losing almost all of its energy
        loop_span_damping_ratio(_spring_and_maxwell(10.0, 1e5, 1.0 / (2 * np.pi * 30.0)), [0.01], 30.0)
