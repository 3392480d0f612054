"""Least-squares fits of the free decay after the impact (Rapp et al. 2022, eq. 13, 14 and 17).

Shared by the extractor (measured logs), the planner (predicted decays: a plan predicts what the
extractor will report), identification and the comparisons, so they all read a decay the same way.

Angle: φ(t) = φ̂·e^(−δt)·cos(ωt − Φ), fitted over (φ̂, δ, ω, Φ) by a compiled Levenberg-Marquardt
from robust starting values, to the minimum :func:`scipy.optimize.least_squares` (MINPACK) finds, which
takes over where it does not converge. Torque (eq. 17): δ and ω
fixed from the angle fit, T(t) = T̂·e^(−δt)·cos(ωt − Φ_T) + offset, which is linear in
(T̂ cos Φ_T, T̂ sin Φ_T, offset) and so solved exactly by linear least squares.
t is the time since the impact onset (s); angles in rad, torques in N·m.

Standard uncertainties: the parameter covariance s²·(JᵀJ)⁻¹ from the Jacobian J at the
solution, scaled by the residual variance s² = Σr²/(n − p), plus the effect of the
uncertain pre-trigger baseline on the angle fit. This is exact for white noise; coloured
noise or model error (Payne effect, setup resonances) make it an underestimate, and a
deterministic disturbance such as the torque ringing an overestimate.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from scipy.optimize import least_squares

from droptower.errors import DroptowerError
from droptower.rheology.numba_cache import cache_available, compile_once_across_processes

_JIT = dict(cache=cache_available(), nogil=True, fastmath=False, error_model="numpy")

HYSTERESIS_FRACTION = 0.05   # zero-crossing band: this fraction of the first peak ...
HYSTERESIS_NOISE = 5.0       # ... or this many noise standard deviations, whichever is larger
START_CROSSINGS = 5          # zero crossings used for the starting frequency
START_PEAKS = 4              # peaks used for the starting decay coefficient
FALLBACK_DECAY_RATIO = 0.05  # δ/ω assumed when fewer than two peaks are in the record
STEP_TOLERANCE = 1e-11       # the decay fit has converged when no parameter moves more than this of its scale
MAX_ITERATIONS = 100         # decay fit: Gauss-Newton steps before MINPACK takes over


@dataclass(frozen=True)
class DecayFit:
    """Fitted angle decay. params = (φ̂ rad, δ 1/s, ω rad/s, Φ rad); cov (4, 4); rms residual (rad)."""

    params: np.ndarray
    cov: np.ndarray
    rms: float

    def __call__(self, t: np.ndarray) -> np.ndarray:
        return decay(self.params, t)


@dataclass(frozen=True)
class TorqueFit:
    """Fitted torque (eq. 17). params = (a, b, offset) with T = e^(−δt)(a cos ωt + b sin ωt) + offset,
    i.e. T̂ = hypot(a, b), Φ_T = atan2(b, a); cov (3, 3); rms residual (N·m)."""

    params: np.ndarray
    cov: np.ndarray
    rms: float
    delta: float
    omega: float

    def __call__(self, t: np.ndarray) -> np.ndarray:
        return torque_model(self.params, self.delta, self.omega, t)


def decay(params: np.ndarray, t: np.ndarray) -> np.ndarray:
    """φ̂·e^(−δt)·cos(ωt − Φ) (Rapp et al. 2022, eq. 13)."""
    amp, delta, omega, phase = params
    return amp * np.exp(-delta * t) * np.cos(omega * t - phase)


def torque_model(params: np.ndarray, delta: float, omega: float, t: np.ndarray) -> np.ndarray:
    """e^(−δt)(a cos ωt + b sin ωt) + offset = T̂ e^(−δt) cos(ωt − Φ_T) + offset (Rapp et al. 2022, eq. 17)."""
    a, b, offset = params
    env = np.exp(-delta * t)
    return env * (a * np.cos(omega * t) + b * np.sin(omega * t)) + offset


def _normal_inverse(jac: np.ndarray) -> np.ndarray:
    """(JᵀJ)⁻¹, with the columns scaled to unit norm first for a well-conditioned inverse."""
    scale = np.linalg.norm(jac, axis=0)
    scale[scale == 0.0] = 1.0
    js = jac / scale
    return np.linalg.pinv(js.T @ js) / np.outer(scale, scale)


def _residual_variance(residual: np.ndarray, n_params: int) -> float:
    """s² = Σr²/(n − p)."""
    return float(residual @ residual) / max(residual.size - n_params, 1)


def zero_crossings(t: np.ndarray, y: np.ndarray, band: float) -> np.ndarray:
    """Times where ``y`` crosses zero, with hysteresis: a crossing is counted only when y goes
    from beyond +band to beyond −band (or back), so noise near zero adds none. The time is
    interpolated linearly between the last sample beyond the band and the first beyond it on
    the other side."""
    side = np.zeros(y.size, dtype=np.int8)
    side[y > band] = 1
    side[y < -band] = -1
    idx = np.flatnonzero(side)
    change = np.flatnonzero(side[idx[1:]] != side[idx[:-1]])
    a, b = idx[change], idx[change + 1]
    return t[a] + (t[b] - t[a]) * y[a] / (y[a] - y[b])


def start_frequency_and_decay(t: np.ndarray, y: np.ndarray, noise: float) -> tuple[float, float]:
    """Starting ω (rad/s) from zero crossings and δ (1/s) from the log decrement of successive peaks.

    t: time since the impact onset, from the end of the contact to the end of the record;
    y: angle minus its pre-trigger baseline. Successive zero crossings of a damped oscillation
    are exactly π/ω apart; the first one is π/ω after the impact. Peaks (the extreme between
    two crossings) fall by e^(−δ·Δt).
    """
    band = max(HYSTERESIS_NOISE * noise, HYSTERESIS_FRACTION * float(np.max(np.abs(y))))
    crossings = zero_crossings(t, y, band)[:START_CROSSINGS]
    if crossings.size == 0:
        raise DroptowerError(f"the record ends {t[-1]:.4g} s after the impact, less than 3/4 of the oscillation "
                             "period (the angle never swings back through its baseline), or the angle does not "
                             "oscillate")
    if crossings.size >= 2:
        omega = np.pi / float(np.mean(np.diff(crossings)))
    else:
        omega = np.pi / float(crossings[0])
    edges = np.searchsorted(t, np.concatenate([[t[0]], crossings, [t[-1]]]))
    peaks_t, peaks_a = [], []
    for lo, hi in zip(edges[:-1], edges[1:]):
        if hi - lo < 3:
            continue
        k = lo + int(np.argmax(np.abs(y[lo:hi])))
        if lo < k < hi - 1:  # a true extreme, not the edge of a truncated segment
            peaks_t.append(t[k])
            peaks_a.append(abs(y[k]))
        if len(peaks_t) == START_PEAKS:
            break
    if len(peaks_t) >= 2:
        delta = -float(np.polyfit(peaks_t, np.log(peaks_a), 1)[0])
    else:
        delta = FALLBACK_DECAY_RATIO * omega
    return omega, max(delta, 0.0)


def _residual_and_jacobian(p: np.ndarray, t: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The residual decay(p, t) - y and its Jacobian over (φ̂, δ, ω, Φ), from one exp, cos and sin."""
    amp, delta, omega, phase = p
    e = np.exp(-delta * t)
    arg = omega * t - phase
    c, s = e * np.cos(arg), e * np.sin(arg)
    return amp * c - y, np.column_stack([c, -t * amp * c, -t * amp * s, amp * s])


def _normal_equations(p, t, y, a, g):
    """Sum of squares of decay(p, t) - y; fills a = JᵀJ (4, 4) and g = Jᵀr (4,) in one pass."""
    amp, delta, omega, phase = p[0], p[1], p[2], p[3]
    a[:] = 0.0
    g[:] = 0.0
    cost = 0.0
    col = np.empty(4)
    for i in range(t.size):
        e = math.exp(-delta * t[i])
        arg = omega * t[i] - phase
        c = e * math.cos(arg)
        s = e * math.sin(arg)
        r = amp * c - y[i]
        col[0] = c
        col[1] = -t[i] * amp * c
        col[2] = -t[i] * amp * s
        col[3] = amp * s
        cost += r * r
        for j in range(4):
            g[j] += col[j] * r
            for k in range(j + 1):
                a[j, k] += col[j] * col[k]
    for j in range(4):
        for k in range(j):
            a[k, j] = a[j, k]
    return cost


def _solve_in_place(m, b):
    """Solve m x = b (n x n, n small) by Gaussian elimination with partial pivoting, the method of
    LAPACK's ``gesv`` (``np.linalg.solve``): m is overwritten, x is left in b. False where a pivot is
    zero (m singular). Written out because numba's binding of ``np.linalg.solve`` costs seconds of
    compilation for a 4 x 4 system."""
    n = b.size
    for k in range(n):
        pivot = k
        largest = abs(m[k, k])
        for i in range(k + 1, n):
            if abs(m[i, k]) > largest:
                pivot, largest = i, abs(m[i, k])
        if not largest > 0.0:
            return False
        if pivot != k:
            for j in range(n):
                m[k, j], m[pivot, j] = m[pivot, j], m[k, j]
            b[k], b[pivot] = b[pivot], b[k]
        for i in range(k + 1, n):
            f = m[i, k] / m[k, k]
            for j in range(k + 1, n):
                m[i, j] -= f * m[k, j]
            b[i] -= f * b[k]
    for k in range(n - 1, -1, -1):
        x = b[k]
        for j in range(k + 1, n):
            x -= m[k, j] * b[j]
        b[k] = x / m[k, k]
    return True


def _levenberg_marquardt(t, y, x0, scale, tolerance, max_iterations):
    """The least-squares decay parameters from x0: Gauss-Newton steps, damped by Marquardt's
    (scaled) diagonal only where a step would raise the sum of squares. Returns (params, True)
    once no parameter moves by more than ``tolerance`` of its ``scale``, (x0, False) if that
    does not happen. (Element by element in loops: numba compiles numpy's array expressions
    for seconds, the loops in a fraction of that, with the same arithmetic.)"""
    p = x0.copy()
    a = np.empty((4, 4))
    g = np.empty(4)
    a_trial = np.empty((4, 4))
    g_trial = np.empty(4)
    a_scaled = np.empty((4, 4))
    g_scaled = np.empty(4)
    d = np.empty(4)
    m = np.empty((4, 4))
    step = np.empty(4)
    trial = np.empty(4)
    cost = _normal_equations(p, t, y, a, g)
    lam = 0.0
    for _ in range(max_iterations):
        if not math.isfinite(cost):
            return x0, False
        for j in range(4):
            d[j] = math.sqrt(a[j, j])
            if not d[j] > 0.0:
                return x0, False
        for j in range(4):
            for k in range(4):
                a_scaled[j, k] = a[j, k] / (d[j] * d[k])
            g_scaled[j] = g[j] / d[j]
        while True:
            for j in range(4):
                for k in range(4):
                    m[j, k] = a_scaled[j, k]
                m[j, j] += lam
                step[j] = -g_scaled[j]
            if not _solve_in_place(m, step):  # singular: MINPACK takes over
                return x0, False
            small = True
            for j in range(4):
                step[j] /= d[j]
                small = small and abs(step[j]) <= tolerance * scale[j]
                trial[j] = p[j] + step[j]
            cost_trial = _normal_equations(trial, t, y, a_trial, g_trial)
            if cost_trial <= cost:
                break
            if small:  # at the minimum up to rounding
                return p, True
            lam = max(10.0 * lam, 1e-3)
            if lam > 1e10:
                return x0, False
        for j in range(4):
            p[j] = trial[j]
            g[j] = g_trial[j]
            for k in range(4):
                a[j, k] = a_trial[j, k]
        cost = cost_trial
        lam = 0.1 * lam if lam > 1e-6 else 0.0
        if small:
            return p, True
    return x0, False


_normal_equations = njit(**_JIT)(_normal_equations)
_solve_in_place = njit(**_JIT)(_solve_in_place)
_levenberg_marquardt = njit(**_JIT)(_levenberg_marquardt)


def fit_decay(t: np.ndarray, y: np.ndarray, omega0: float, delta0: float, baseline_var: float = 0.0) -> DecayFit:
    """Least-squares fit of φ̂ e^(−δt) cos(ωt − Φ) to (t, y) (Rapp et al. 2022, eq. 13-14).

    Starting amplitude and phase come from the linear least-squares solution for the given
    starting ω and δ (robust against noise in any single sample). baseline_var: variance of
    the baseline subtracted from y (rad²); a baseline error b shifts the solution by
    b·(JᵀJ)⁻¹Jᵀ1 (over one cycle it mimics decay), which is added to the covariance.
    """
    env = np.exp(-delta0 * t)
    basis = np.column_stack([env * np.cos(omega0 * t), env * np.sin(omega0 * t)])
    (a, b), *_ = np.linalg.lstsq(basis, y, rcond=None)
    x0 = np.array([np.hypot(a, b), delta0, omega0, np.arctan2(b, a)])

    scale = np.array([abs(x0[0]), abs(x0[2]), abs(x0[2]), 1.0])  # φ̂ of the amplitude, δ and ω of the frequency
    converged = False
    if np.all(np.isfinite(x0)) and np.all(scale > 0):
        params, converged = _levenberg_marquardt(np.ascontiguousarray(t, np.float64),
                                                 np.ascontiguousarray(y, np.float64), x0, scale, STEP_TOLERANCE,
                                                 MAX_ITERATIONS)
    if not converged:  # a signal far from a decay: MINPACK's safeguarded search
        sol = least_squares(lambda p: _residual_and_jacobian(p, t, y)[0], x0,
                            jac=lambda p: _residual_and_jacobian(p, t, y)[1], method="lm", x_scale="jac")
        params = sol.x
    params = params.copy()
    if params[0] < 0:  # same curve, positive amplitude
        params[0], params[3] = -params[0], params[3] + np.pi
    params[3] = float(np.angle(np.exp(1j * params[3])))
    r, jac = _residual_and_jacobian(params, t, y)
    inverse = _normal_inverse(jac)
    shift = inverse @ jac.sum(axis=0)
    cov = _residual_variance(r, 4) * inverse + baseline_var * np.outer(shift, shift)
    return DecayFit(params, cov, float(np.sqrt(np.mean(r**2))))


def fit_torque(t: np.ndarray, y: np.ndarray, delta: float, omega: float) -> TorqueFit:
    """Linear least-squares fit of eq. 17 with δ, ω fixed: T̂, Φ_T and an offset."""
    env = np.exp(-delta * t)
    basis = np.column_stack([env * np.cos(omega * t), env * np.sin(omega * t), np.ones_like(t)])
    params, *_ = np.linalg.lstsq(basis, y, rcond=None)
    r = basis @ params - y
    cov = _residual_variance(r, 3) * _normal_inverse(basis)
    return TorqueFit(params, cov, float(np.sqrt(np.mean(r**2))), delta, omega)

compile_once_across_processes(globals())  # a kernel no cache holds is compiled by one process at a time
