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
