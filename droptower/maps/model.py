"""The characteristic map of seed 004 (eq. 19 and eq. 20, NOTES §1.5) as pure functions.

Units are the paper's, because the coefficients only mean something in them: amplitude φ̂ in
degrees, frequency f in Hz, stiffness c in N·m/deg, damping ratio d dimensionless.

    eq. 19   c(φ̂, f) = k1·10^(−k2·φ̂) + k3·10^(−k4·φ̂) + k5·√f + k6·10^(−k7·f)
    eq. 20   c/d(φ̂)  = k8·10^(−k9·φ̂) + k10·10^(−k11·φ̂) + k12·10^(−k13·φ̂)

so the damping ratio is d(φ̂, f) = c(φ̂, f) / (eq. 20). Both equations are linear in the
coefficients in front of the terms once the exponents (k2, k4, k7; k9, k11, k13) are fixed:
:func:`stiffness_basis` and :func:`ratio_basis` give those linear columns (variable projection).
"""
from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

#: Coefficient names of eq. 19 and eq. 20 with the unit of each (its output-name suffix).
STIFFNESS_UNITS: dict[str, str] = {
    "k1": "nm_per_deg", "k2": "per_deg", "k3": "nm_per_deg", "k4": "per_deg",
    "k5": "nm_per_deg_per_sqrt_hz", "k6": "nm_per_deg", "k7": "per_hz",
}
RATIO_UNITS: dict[str, str] = {
    "k8": "nm_per_deg", "k9": "per_deg", "k10": "nm_per_deg", "k11": "per_deg",
    "k12": "nm_per_deg", "k13": "per_deg",
}
#: Where the linear coefficients and the exponents sit in the parameter vectors.
STIFFNESS_LINEAR = (0, 2, 4, 5)      # k1, k3, k5, k6
STIFFNESS_EXPONENTS = (1, 3, 6)      # k2, k4, k7
RATIO_LINEAR = (0, 2, 4)             # k8, k10, k12
RATIO_EXPONENTS = (1, 3, 5)          # k9, k11, k13


def stiffness_basis(exponents: ArrayLike, amplitude_deg: ArrayLike, frequency_hz: ArrayLike) -> np.ndarray:
    """Columns of eq. 19 for fixed exponents (k2, k4, k7): (N, 4) so that c = basis @ (k1, k3, k5, k6)."""
    k2, k4, k7 = np.asarray(exponents, dtype=float)
    a = np.asarray(amplitude_deg, dtype=float)
    f = np.asarray(frequency_hz, dtype=float)
    return np.stack(np.broadcast_arrays(10.0 ** (-k2 * a), 10.0 ** (-k4 * a), np.sqrt(f), 10.0 ** (-k7 * f)), axis=-1)


def ratio_basis(exponents: ArrayLike, amplitude_deg: ArrayLike) -> np.ndarray:
    """Columns of eq. 20 for fixed exponents (k9, k11, k13): (N, 3) so that c/d = basis @ (k8, k10, k12)."""
    e = np.asarray(exponents, dtype=float)
    a = np.asarray(amplitude_deg, dtype=float)
    return 10.0 ** (-a[..., None] * e)


def stiffness(params: ArrayLike, amplitude_deg: ArrayLike, frequency_hz: ArrayLike) -> np.ndarray:
    """Eq. 19: dynamic stiffness (N·m/deg) at amplitude (deg) and frequency (Hz); params k1..k7."""
    p = np.asarray(params, dtype=float)
    return stiffness_basis(p[list(STIFFNESS_EXPONENTS)], amplitude_deg, frequency_hz) @ p[list(STIFFNESS_LINEAR)]


def stiffness_over_damping(params: ArrayLike, amplitude_deg: ArrayLike) -> np.ndarray:
    """Eq. 20: stiffness over damping ratio c/d (N·m/deg) at amplitude (deg); params k8..k13."""
    p = np.asarray(params, dtype=float)
    return ratio_basis(p[list(RATIO_EXPONENTS)], amplitude_deg) @ p[list(RATIO_LINEAR)]


def damping_ratio(stiffness_params: ArrayLike, ratio_params: ArrayLike,
                  amplitude_deg: ArrayLike, frequency_hz: ArrayLike) -> np.ndarray:
    """Damping ratio (-) from the map: eq. 19 divided by eq. 20 (seed 004, text after eq. 20)."""
    return stiffness(stiffness_params, amplitude_deg, frequency_hz) / stiffness_over_damping(ratio_params, amplitude_deg)


def _exp_term_derivatives(coefficient: float, exponent: float, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """d/d(coefficient) and d/d(exponent) of coefficient·10^(−exponent·x)."""
    e = 10.0 ** (-exponent * x)
    return e, -coefficient * np.log(10.0) * x * e


def stiffness_jacobian(params: ArrayLike, amplitude_deg: ArrayLike, frequency_hz: ArrayLike) -> np.ndarray:
    """∂c/∂(k1..k7) of eq. 19 at each test: (N, 7)."""
    k1, k2, k3, k4, k5, k6, k7 = np.asarray(params, dtype=float)
    a, f = np.broadcast_arrays(np.asarray(amplitude_deg, float), np.asarray(frequency_hz, float))
    return np.stack([*_exp_term_derivatives(k1, k2, a), *_exp_term_derivatives(k3, k4, a),
                     np.sqrt(f), *_exp_term_derivatives(k6, k7, f)], axis=-1)


def ratio_jacobian(params: ArrayLike, amplitude_deg: ArrayLike) -> np.ndarray:
    """∂(c/d)/∂(k8..k13) of eq. 20 at each test: (N, 6)."""
    p = np.asarray(params, dtype=float)
    a = np.asarray(amplitude_deg, dtype=float)
    return np.stack([d for i in RATIO_LINEAR for d in _exp_term_derivatives(p[i], p[i + 1], a)], axis=-1)
