"""The single-degree-of-freedom decay J φ'' + d φ' + c φ = 0 and what it yields: stiffness and
damping from the decay parameters (Rapp et al. 2022, eq. 15, 16, 18, decoded in docs/theory.md#extraction) and the
servo-comparable damping measures of docs/theory.md#damping-measures.

One module that the rig (planning), the extractor and the servo bench all use, so the
drop tower's and the servo bench's damping are converted by the same formulas. All functions
are pure and vectorised. delta: decay coefficient δ (1/s); omega: damped angular frequency
ω (rad/s); inertia: rotating inertia J (kg·m²).
"""
from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

#: the axis label and header of Rapp's damping ratio (not Lehr's D)
DAMPING_LABEL = "d = E_diss/E_el (Rapp et al. 2022) [-]"


def stiffness(inertia: ArrayLike, omega: ArrayLike, delta: ArrayLike) -> np.ndarray:
    """Dynamic stiffness c_dyn,M1 = J·(ω² + δ²) in N·m/rad (Rapp et al. 2022, eq. 15, decoded in docs/theory.md#extraction).

    For J φ'' + d φ' + c φ = 0 the damped frequency is ω² = c/J − δ², hence c = J(ω² + δ²).
    """
    omega, delta = np.asarray(omega, float), np.asarray(delta, float)
    return np.asarray(inertia, float) * (omega**2 + delta**2)


def damping_ratio(delta: ArrayLike, omega: ArrayLike) -> np.ndarray:
    """d_ratio = E_diss / E_el = ½·(e^(4πδ/ω) − 1) (Rapp et al. 2022, eq. 16, decoded in docs/theory.md#extraction)."""
    return 0.5 * np.expm1(4.0 * np.pi * np.asarray(delta, float) / np.asarray(omega, float))


def decay_ratio(damping_ratio_: ArrayLike) -> np.ndarray:
    """r = δ/ω from d_ratio: the inverse of :func:`damping_ratio`, r = ln(1 + 2 d_ratio) / (4π)."""
    return np.log1p(2.0 * np.asarray(damping_ratio_, float)) / (4.0 * np.pi)


def stiffness_from_map(inertia: ArrayLike, frequency_hz: ArrayLike, damping_ratio_: ArrayLike) -> np.ndarray:
    """c = J(ω² + δ²) in N·m/rad from a map row (J, f, d_ratio): ω = 2πf, δ = ω·r(d_ratio).

    This is how docs/theory.md#extraction checks Table 4 of Rapp et al. 2022 against eq. 15 and 16.
    """
    omega = 2.0 * np.pi * np.asarray(frequency_hz, float)
    return stiffness(inertia, omega, omega * decay_ratio(damping_ratio_))


def reference_amplitude(amplitude: ArrayLike, delta: ArrayLike, window_s: ArrayLike) -> np.ndarray:
    """φ̂_ref = φ̂·e^(−δ·t_max/2): the envelope in the middle of the fit window of length t_max
    (Rapp et al. 2022, eq. 18, docs/theory.md#extraction). Same unit as ``amplitude``."""
    return np.asarray(amplitude, float) * np.exp(-np.asarray(delta, float) * np.asarray(window_s, float) / 2.0)


def loss_factor(delta: ArrayLike, omega: ArrayLike) -> np.ndarray:
    """Servo-comparable loss factor η = K''/K' = 2r/(1 + r²), r = δ/ω (docs/theory.md#damping-measures).

    The loss factor a servo-hydraulic bench would measure (ISO 4664-1, DIN 740-2) on the
    linear Kelvin–Voigt coupling that has this decay, excited at its own damped frequency ω:
    K' = c = J(ω² + δ²), K'' = d·ω = 2Jδω.
    """
    r = np.asarray(delta, float) / np.asarray(omega, float)
    return 2.0 * r / (1.0 + r**2)


def lehr_damping(delta: ArrayLike, omega: ArrayLike) -> np.ndarray:
    """Lehr's damping D (ζ, the "damping ratio" of a drivetrain engineer) of the decay with δ and ω:
    D = r/√(1 + r²), r = δ/ω (docs/theory.md#damping-measures).

    For J φ'' + d φ' + c φ = 0: δ = Dω₀ and ω = ω₀√(1 − D²) with ω₀² = c/J, hence r = D/√(1 − D²).
    Not Rapp's d = E_diss/E_el of :func:`damping_ratio`: at r = 0.1, D = 0.0995 but d = 1.26.
    """
    r = np.asarray(delta, float) / np.asarray(omega, float)
    return r / np.sqrt(1.0 + r**2)


def damping_measures(damping_ratio_: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """(Lehr's D, loss factor η) of the linear Kelvin–Voigt decay whose Rapp d = E_diss/E_el is
    given (docs/theory.md#damping-measures): r from :func:`decay_ratio`, then :func:`lehr_damping`
    and :func:`loss_factor` (δ = r, ω = 1)."""
    r = decay_ratio(damping_ratio_)
    return lehr_damping(r, 1.0), loss_factor(r, 1.0)


def relative_damping(delta: ArrayLike, omega: ArrayLike) -> np.ndarray:
    """Servo-comparable relative damping ψ = W_D / W_el with W_el = ½·T̂·φ̂ (DIN 740-2, docs/theory.md#damping-measures).

    Same linear Kelvin–Voigt coupling as :func:`loss_factor`: damping work per cycle
    W_D = π K'' φ̂², torque amplitude T̂ = |K*| φ̂, so ψ = 2π K''/|K*| = 2πη / √(1 + η²)
    (≈ 2πη, the approximation docs/theory.md#damping-measures quotes). This is not the drop tower's d_ratio
    (eq. 16): at r = 0.05, ψ = 0.62 but d_ratio = 0.44.
    """
    eta = loss_factor(delta, omega)
    return 2.0 * np.pi * eta / np.sqrt(1.0 + eta**2)


def decay_ratio_from_loss_factor(loss_factor_: ArrayLike) -> np.ndarray:
    """r = δ/ω of the linear Kelvin–Voigt coupling whose loss factor is η = 2r/(1 + r²) (docs/theory.md#damping-measures):
    r = (1 − √(1 − η²))/η; NaN where no such coupling exists (η < 0 or η > 1)."""
    eta = np.asarray(loss_factor_, dtype=float)
    with np.errstate(invalid="ignore", divide="ignore"):
        r = np.where(eta == 0.0, 0.0, (1.0 - np.sqrt(1.0 - eta * eta)) / eta)
    return np.where((eta >= 0.0) & (eta <= 1.0), r, np.nan)


def drop_tower_equivalent_damping_ratio(loss_factor_: ArrayLike) -> np.ndarray:
    """The drop tower's damping ratio d = E_diss / E_el (Rapp et al. 2022, eq. 16, docs/theory.md#extraction) of the
    linear Kelvin–Voigt coupling with the given (servo-measured) loss factor: what the drop
    tower would report for it, swinging freely at its damped frequency (docs/theory.md#damping-measures)."""
    return 0.5 * np.expm1(4.0 * np.pi * decay_ratio_from_loss_factor(loss_factor_))
