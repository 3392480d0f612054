"""The package's one first-order propagation (droptower.propagation): exact on a linear map,
the GUM's closed form c = J·ω² on a product, and the same numbers vectorised or not."""
from __future__ import annotations

import numpy as np
from hypothesis import given, settings, strategies as st

from droptower.propagation import propagate, sensitivities


@settings(derandomize=True, max_examples=30, deadline=None)
@given(st.integers(min_value=1, max_value=4), st.integers(min_value=1, max_value=4), st.integers(0, 2**31 - 1))
def test_linear_map_gives_a_cov_at_exactly(m, p, seed):
    """y = A·x: u(y)² = diag(A·Σ·Aᵀ) (GUM 5.2.2, exact for a linear model), correlations included."""
    rng = np.random.default_rng(seed)
    a, x = rng.normal(size=(m, p)), rng.normal(size=p)
    root = rng.normal(size=(p, p))
    cov = root @ root.T + 1e-3 * np.eye(p)
    value, u = propagate(lambda v: a @ v, x, cov)
    np.testing.assert_allclose(value, a @ x, rtol=1e-12)
    np.testing.assert_allclose(u, np.sqrt(np.diag(a @ cov @ a.T)), rtol=1e-6)


def test_stiffness_from_inertia_and_frequency_follows_the_closed_form():
    """c = J·ω²: (u_c/c)² = (u_J/J)² + (2·u_ω/ω)² (docs/guide/uncertainty.md, first order)."""
    j, omega, uj, uw = 0.359, 2 * np.pi * 30.0, 0.0036, 0.2
    value, u = propagate(lambda v: np.array([v[0] * v[1] ** 2]), np.array([j, omega]), np.diag([uj ** 2, uw ** 2]))
    assert value[0] == j * omega ** 2
    np.testing.assert_allclose(u[0] / value[0], np.hypot(uj / j, 2 * uw / omega), rtol=1e-6)


def test_vectorised_and_per_column_evaluations_agree():
    fun = lambda v: np.array([np.sin(v[0]) * v[1], np.exp(v[1]) + v[0] ** 3])  # noqa: E731
    x, steps = np.array([0.3, -1.2]), np.array([1e-4, 2e-4])
    v1, g1 = sensitivities(fun, x, steps)
    v2, g2 = sensitivities(fun, x, steps, vectorised=True)
    np.testing.assert_allclose(v1, v2)
    np.testing.assert_allclose(g1, g2, rtol=1e-9)
    np.testing.assert_allclose(g1, [[np.cos(0.3) * -1.2, np.sin(0.3)], [3 * 0.3 ** 2, np.exp(-1.2)]], rtol=1e-6)


def test_a_parameter_known_to_a_million_times_its_size_gets_its_derivative_not_an_overflow():
    """A map's loosely determined decay exponent (u = 2.5e6 on e = 1.68, a tutorial's eq. 20):
    y = k·10^(−e·a) has ∂y/∂e = −a·ln10·y, so u(y) = a·ln10·y·u_e exactly to first order. A step
    of 1e-3 u (2 500 on 1.68) overflowed 10^(−e·a) and gave bands hundreds of times the value;
    the step now scales with the value where u exceeds it."""
    k, e, a, ue = 5.83, 1.68, 0.3, 2.5e6
    with np.errstate(over="raise", invalid="raise"):
        value, u = propagate(lambda v: np.array([v[0] * 10.0 ** (-v[1] * a)]), np.array([k, e]),
                             np.diag([0.01 ** 2, ue ** 2]))
    y = k * 10.0 ** (-e * a)
    np.testing.assert_allclose(u[0], np.hypot(0.01 * y / k, a * np.log(10) * y * ue), rtol=1e-6)


@settings(derandomize=True, max_examples=30, deadline=None)
@given(st.floats(-3.0, 3.0), st.floats(-5.0, 7.0))
def test_the_steps_give_the_closed_form_whatever_the_uncertainty_against_the_value(log_x, log_u_over_x):
    """y = x³ at any x and any u from 1e-5 to 1e7 times x: u(y) = 3x²·u to first order."""
    x = 10.0 ** log_x
    ux = x * 10.0 ** log_u_over_x
    value, u = propagate(lambda v: v ** 3, np.array([x]), np.array([[ux ** 2]]))
    np.testing.assert_allclose(u[0], 3 * x ** 2 * ux, rtol=1e-5)
