"""Least-squares fits of the free decay after the impact (Rapp et al. 2022, eq. 13, 14 and 17).

Shared by the extractor (measured logs), the planner (predicted decays: a plan predicts what the
extractor will report), identification and the comparisons, so they all read a decay the same way.

Angle: φ(t) = φ̂·e^(−δt)·cos(ωt − Φ), fitted over (φ̂, δ, ω, Φ) by a compiled Levenberg-Marquardt
from robust starting values (:mod:`droptower.damped_cosine_kernels`), to the minimum :func:`scipy.optimize.least_squares` (MINPACK) finds, which
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

from dataclasses import dataclass

import numpy as np

from droptower.errors import DroptowerError

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
        # compiled on first use: importing this module (every command that reads a log) loads no numba
        from droptower.damped_cosine_kernels import levenberg_marquardt

        params, converged = levenberg_marquardt(np.ascontiguousarray(t, np.float64),
                                                 np.ascontiguousarray(y, np.float64), x0, scale, STEP_TOLERANCE,
                                                 MAX_ITERATIONS)
    if not converged:  # a signal far from a decay: MINPACK's safeguarded search
        from scipy.optimize import least_squares  # here: scipy.optimize takes ~0.3 s to import

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
