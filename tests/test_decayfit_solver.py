"""The decay fit's compiled Levenberg-Marquardt finds the minimum MINPACK finds (droptower/damped_cosine.py, droptower/damped_cosine_kernels.py)."""
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import least_squares

from droptower import damped_cosine as D
from droptower import damped_cosine_kernels as DK


@settings(max_examples=60, deadline=None, derandomize=True)
@given(omega=st.floats(150.0, 900.0), ratio=st.floats(0.0, 0.3), amp=st.floats(1e-3, 0.2), phase=st.floats(-1.5, 1.5),
       n=st.integers(200, 3000), noise=st.floats(1e-6, 1e-2), off=st.floats(0.85, 1.15), seed=st.integers(0, 2**32 - 1))
def test_same_minimum_as_minpack(omega, ratio, amp, phase, n, noise, off, seed):
    """Random decays, noise from 1e-6 to 1 % of the amplitude, starting frequency 15 % off: the
    parameters agree with MINPACK's (scipy ``least_squares(method="lm")``) within 1e-3 of their
    1-sigma (MINPACK stops at 1e-8 of the parameters) and the rms residual within 1e-9."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 38400.0
    y = D.decay(np.array([amp, ratio * omega, omega, phase]), t) + rng.normal(0.0, noise * amp, n)
    omega0, delta0 = off * omega, ratio * omega / off
    fit = D.fit_decay(t, y, omega0, delta0)
    env = np.exp(-delta0 * t)
    (a, b), *_ = np.linalg.lstsq(np.column_stack([env * np.cos(omega0 * t), env * np.sin(omega0 * t)]), y, rcond=None)
    x0 = np.array([np.hypot(a, b), delta0, omega0, np.arctan2(b, a)])
    ref = least_squares(lambda p: D._residual_and_jacobian(p, t, y)[0], x0,
                        jac=lambda p: D._residual_and_jacobian(p, t, y)[1], method="lm", x_scale="jac").x
    if ref[0] < 0:
        ref[0], ref[3] = -ref[0], ref[3] + np.pi
    ref[3] = float(np.angle(np.exp(1j * ref[3])))
    sigma = np.sqrt(np.diag(fit.cov))
    assert np.all(np.abs(fit.params - ref) <= 1e-3 * sigma), (fit.params - ref) / sigma
    rms = np.sqrt(np.mean(D._residual_and_jacobian(ref, t, y)[0] ** 2))
    assert abs(fit.rms - rms) <= 1e-9 * rms


def test_minpack_takes_over_where_it_does_not_converge():
    """A record that is no decay at all (a constant): the compiled solver gives up, MINPACK answers."""
    t = np.arange(500) / 38400.0
    y = np.full(500, 0.01)
    scale = np.array([1.0, 500.0, 500.0, 1.0])
    _, converged = DK.levenberg_marquardt(t, y, np.array([0.01, 0.0, 500.0, 0.0]), scale, D.STEP_TOLERANCE, 3)
    assert not converged
    fit = D.fit_decay(t, y, 500.0, 0.0)
    assert np.all(np.isfinite(fit.params))


@settings(max_examples=60, deadline=None, derandomize=True)
@given(n=st.integers(1, 6), seed=st.integers(0, 2**32 - 1), lam=st.floats(0.0, 1e3), permute=st.booleans())
def test_small_solve_equals_lapack(n, seed, lam, permute):
    """The hand-written solve of the Marquardt step: random scaled normal matrices plus lam I
    (symmetric positive definite, as in the fit) and, permuted, matrices that need row pivoting
    (zero on the diagonal): the solution of np.linalg.solve (LAPACK gesv) to rounding."""
    rng = np.random.default_rng(seed)
    jac = rng.normal(size=(3 * n, n)) * 10.0 ** rng.uniform(-3, 3, n)
    a = jac.T @ jac
    d = np.sqrt(np.diag(a))
    m = a / np.outer(d, d) + lam * np.eye(n)
    if permute and n > 1:
        m = np.roll(m, 1, axis=0)
        m[np.arange(n), np.arange(n)] = 0.0
    b = rng.normal(size=n)
    x, mm = b.copy(), m.copy()
    assert DK.solve_in_place(mm, x)
    ref = np.linalg.solve(m, b)
    cond = np.linalg.cond(m)
    assert np.allclose(x, ref, rtol=0.0, atol=1e-14 * cond * np.max(np.abs(ref)))


def test_small_solve_reports_a_singular_matrix():
    """A zero pivot (a column of zeros, or a row equal to another) is reported, not divided by."""
    m = np.array([[1.0, 0.0, 2.0], [3.0, 0.0, 1.0], [0.5, 0.0, 4.0]])
    assert not DK.solve_in_place(m.copy(), np.ones(3))
    m = np.array([[1.0, 2.0], [1.0, 2.0]])
    assert not DK.solve_in_place(m.copy(), np.ones(2))
