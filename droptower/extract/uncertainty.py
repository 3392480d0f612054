"""Linear propagation of a parameter covariance through a function (GUM, first order)."""
from __future__ import annotations

from typing import Callable

import numpy as np


def propagate(fun: Callable[[np.ndarray], np.ndarray], x: np.ndarray, cov: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Values ``fun(x)`` and their standard uncertainties sqrt(diag(G·cov·Gᵀ)).

    G, the Jacobian of ``fun`` at ``x``, by central differences with steps of 1e-3 standard
    uncertainties (so the linearisation holds on the scale of the uncertainty itself).
    """
    x = np.asarray(x, dtype=float)
    value = np.asarray(fun(x), dtype=float)
    sd = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    steps = np.where(sd > 0, 1e-3 * sd, 1e-8 * np.maximum(np.abs(x), 1.0))
    grad = np.empty((value.size, x.size))
    for i, h in enumerate(steps):
        dx = np.zeros_like(x)
        dx[i] = h
        grad[:, i] = (np.asarray(fun(x + dx)) - np.asarray(fun(x - dx))) / (2.0 * h)
    var = np.einsum("ij,jk,ik->i", grad, cov, grad)
    return value, np.sqrt(np.clip(var, 0.0, None))
