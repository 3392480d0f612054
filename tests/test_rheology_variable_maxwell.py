"""The variable Maxwell branch of the six-parameter model, (k0 + g|e|) e in series with a
constant dashpot c: its step solves backward Euler's quadratic in closed form
(:func:`droptower.rheology.kernels.variable_maxwell`); the tables' branch iterates. Both are
held against the equation itself and against each other on random parameters and histories."""
from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from droptower.rheology import kernels as K
from droptower.rheology import parse_coupling

log_uniform = lambda lo, hi: st.floats(np.log10(lo), np.log10(hi)).map(lambda v: float(10 ** v))  # noqa: E731


def _branch(k0: float, gain: float, c: float, table_to: float | None = None):
    """The branch with the constants, or (``table_to``) with the same law as a stiffness table
    k(e) = k0 + g|e|, exact up to |e| = table_to (the table is linear between its knots)."""
    if table_to is None:
        el = {"kind": "variable_maxwell", "stiffness": k0, "stiffness_gain": gain, "damping": c}
    else:
        el = {"kind": "variable_maxwell", "damping": c, "stiffness_table": {
            "x": [-table_to, 0.0, table_to], "y": [k0 + gain * table_to, k0, k0 + gain * table_to]}}
    return parse_coupling({"name": "branch", "element": [el]})


@settings(max_examples=60, deadline=None, derandomize=True)
@given(log_uniform(1.0, 1e6), st.one_of(st.just(0.0), log_uniform(1e-2, 1e9)), log_uniform(1e-4, 1e3),
       st.sampled_from([1 / 38400, 1 / 2048, 1 / 50]), st.integers(0, 2 ** 16))
def test_closed_form_step_solves_backward_euler_and_equals_the_iteration(k0, gain, c, h, seed):
    """At random springs (1 to 1e6 N*m/rad, gains up to 1e9 N*m/rad^2 or none), dashpots
    (1e-4 to 1e3 N*m*s/rad) and steps, along a random walk of 400 steps (up to 0.1 rad): each
    step's elongation solves (k0 + g|e|) e = (c/h)(e0 + dx - e) to 1e-12 of its terms, and the
    torque history equals the tables' iterated one (the same law as a table) to 1e-9 of its peak."""
    rng = np.random.default_rng(seed)
    angle = np.cumsum(rng.normal(0.0, 1.0, 400))
    angle *= 0.1 / max(np.max(np.abs(angle)), 1e-12)
    closed = _branch(k0, gain, c)
    state = closed.new_state(1)
    slot = int(closed.s_off[0]) + K.S_VARIABLE_MAXWELL_ELONGATION_RAD
    e0, x0 = 0.0, 0.0
    for x1 in angle:
        closed.step(state, x1, h)
        e = float(state.values[0, slot])
        spring, dashpot = (k0 + gain * abs(e)) * e, c / h * (x1 - x0 - (e - e0))
        assert abs(spring - dashpot) <= 1e-12 * (abs(spring) + c / h * (abs(x1 - x0) + abs(e) + abs(e0)))
        e0, x0 = e, x1
    torque = closed.respond(angle, h)
    iterated = _branch(k0, gain, c, table_to=1.0).respond(angle, h)
    assert np.max(np.abs(torque - iterated)) <= 1e-9 * np.max(np.abs(iterated))
