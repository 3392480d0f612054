"""The characteristic map of Rapp et al. 2022 (eq. 19 and eq. 20) as pure functions.

Units are the paper's, because the coefficients only mean something in them: amplitude φ̂ in
degrees, frequency f in Hz, stiffness c in N·m/deg, damping ratio d dimensionless.

    eq. 19   c(φ̂, f) = k1·10^(−k2·φ̂) + k3·10^(−k4·φ̂) + k5·√f + k6·10^(−k7·f)
    eq. 20   c/d(φ̂)  = k8·10^(−k9·φ̂) + k10·10^(−k11·φ̂) + k12·10^(−k13·φ̂)

so the damping ratio is d(φ̂, f) = c(φ̂, f) / (eq. 20). The equations are defined once, as the
paper's :class:`~droptower.maps.forms.MapForm` (:data:`~droptower.maps.forms.PAPER`); these are
its values.
"""
from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from droptower.maps.forms import PAPER


def stiffness(params: ArrayLike, amplitude_deg: ArrayLike, frequency_hz: ArrayLike) -> np.ndarray:
    """Eq. 19: dynamic stiffness (N·m/deg) at amplitude (deg) and frequency (Hz); params k1..k7."""
    return PAPER.stiffness.value(params, amplitude_deg, frequency_hz)


def stiffness_over_damping(params: ArrayLike, amplitude_deg: ArrayLike) -> np.ndarray:
    """Eq. 20: stiffness over damping ratio c/d (N·m/deg) at amplitude (deg); params k8..k13."""
    return PAPER.ratio.value(params, amplitude_deg, 0.0)  # eq. 20 does not depend on the frequency


def damping_ratio(stiffness_params: ArrayLike, ratio_params: ArrayLike,
                  amplitude_deg: ArrayLike, frequency_hz: ArrayLike) -> np.ndarray:
    """Damping ratio (-) from the map: eq. 19 divided by eq. 20 (Rapp et al. 2022, text after eq. 20)."""
    return stiffness(stiffness_params, amplitude_deg, frequency_hz) / stiffness_over_damping(ratio_params, amplitude_deg)
