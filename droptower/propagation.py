"""The GUM's law of propagation, first order (JCGM 100:2008, 5.1.2; docs/guide/uncertainty.md):
sensitivity coefficients ∂f/∂x_i by central differences and u_c(y)² = g·Σ·gᵀ.

The one implementation of it in the package: the extractor's ``*_std`` (the fit's covariance
through the derived quantities, :mod:`droptower.extract.extractor`) and the uncertainty budget
(the fit and the rig's inputs, :mod:`droptower.uncertainty.gum`) both use it. It sits below
both so that the extraction never imports the budget's package (which imports the extractor).
"""
from __future__ import annotations

from typing import Callable

import numpy as np

#: central-difference step, in standard uncertainties of each input (the linearisation on the
#: scale of the uncertainty itself)
STEP_IN_U = 1e-3


def sensitivities(fun: Callable[[np.ndarray], np.ndarray], x: np.ndarray, steps: np.ndarray, *,
                  vectorised: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Values ``fun(x)`` (m,) and the sensitivity coefficients G (m, p), G[j, i] = ∂f_j/∂x_i, by
    central differences of step ``steps[i]`` (x's unit, > 0).

    ``fun`` maps x (p,) to (m,); with ``vectorised`` it maps columns (p, N) to (m, N) and is
    called once on the centre and every ± step together.
    """
    x = np.asarray(x, dtype=float)
    steps = np.asarray(steps, dtype=float)
    columns = np.repeat(x[:, None], 1 + 2 * x.size, axis=1)
    for i, h in enumerate(steps):
        columns[i, 1 + 2 * i] += h
        columns[i, 2 + 2 * i] -= h
    if vectorised:
        out = np.asarray(fun(columns), dtype=float)
    else:
        out = np.stack([np.asarray(fun(columns[:, j]), dtype=float) for j in range(columns.shape[1])], axis=1)
    out = out.reshape(-1, columns.shape[1])
    grad = (out[:, 1::2] - out[:, 2::2]) / (2.0 * steps)
    return out[:, 0], grad


def propagate(fun: Callable[[np.ndarray], np.ndarray], x: np.ndarray, cov: np.ndarray, *,
              vectorised: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Values ``fun(x)`` and their standard uncertainties sqrt(diag(G·cov·Gᵀ)) (GUM 5.2.2).

    G by :func:`sensitivities` with steps of :data:`STEP_IN_U` standard uncertainties
    (sqrt(diag(cov))); a parameter less certain than its own size (u > |x|) steps by
    :data:`STEP_IN_U` of its size instead (not below 1e-9 u), and one of zero variance by 1e-8
    of its size.
    """
    x = np.asarray(x, dtype=float)
    sd = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    # the derivative is taken where the function is linear: a step of 1e-3 u is that for a
    # parameter known to better than its size, but not for one known to 10⁶ times its size (a
    # map's loosely determined decay exponent, u = 2.5e6 on 1.68: 10^(-e·a) overflows over the
    # step, and the "band" came out 700 times the value). The step then scales with the value.
    scale = np.minimum(sd, np.maximum(np.abs(x), 1e-9 * sd))
    steps = np.where(sd > 0, STEP_IN_U * scale, 1e-8 * np.maximum(np.abs(x), 1.0))
    value, grad = sensitivities(fun, x, steps, vectorised=vectorised)
    var = np.einsum("ij,jk,ik->i", grad, cov, grad)
    return value, np.sqrt(np.clip(var, 0.0, None))
