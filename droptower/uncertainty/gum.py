"""The GUM's law of propagation of uncertainty (JCGM 100:2008, 5.1.2) on a drop's measurement
model: sensitivity coefficients c_i = ∂f/∂x_i by central differences
(:func:`droptower.propagation.sensitivities`, the package's one first-order propagation) through the extraction's
own equations (:class:`~droptower.uncertainty.model.DropModel`), contributions u_i(y) = |c_i|·u(x_i),
the fit's contribution √(g·Σ_θ·gᵀ) from its covariance, and u_c(y)² their sum of squares.

The inputs are independent of each other and of the fit within one drop (each comes from its
own certificate or tolerance); first order, so adequate where the model is near linear over the
inputs' spread and the output near normal (checked against Monte Carlo in :mod:`.budget`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from droptower.errors import expects
from droptower.propagation import STEP_IN_U, sensitivities
from droptower.uncertainty.inputs import DropInputs
from droptower.uncertainty.model import QUANTITIES, DropModel

#: the budget's name of the fit's contribution
FIT = "fit"


@dataclass(frozen=True)
class GumPropagation:
    """First-order propagation on one drop, per quantity (SI): ``values``; ``sensitivity``
    quantity -> input -> c_i (unit of y per unit of x_i); ``contributions`` quantity -> source
    (an input or ``"fit"``) -> u_i(y) ≥ 0; ``standard_uncertainty`` u_c(y)."""

    values: dict[str, float]
    sensitivity: dict[str, dict[str, float]]
    contributions: dict[str, dict[str, float]]
    standard_uncertainty: dict[str, float]


@expects(model=DropModel, inputs=DropInputs)
def propagate_gum(model: DropModel, inputs: DropInputs) -> GumPropagation:
    """Combined standard uncertainty and budget of every quantity of one drop (GUM 5.1.2).

    Parameters
    ----------
    model : DropModel
        The drop's measurement model (fitted θ with its covariance, nominal inputs).
    inputs : DropInputs
        The given inputs with their standard uncertainties.

    Returns
    -------
    GumPropagation
        Values, sensitivity coefficients, contributions (the fit's and each input's) and u_c per quantity.
    """
    model.check_inputs(inputs.given)
    theta = model.theta
    sd = np.sqrt(np.clip(np.diag(model.cov), 0.0, None))
    fit_params = np.flatnonzero(sd > 0)
    given = list(inputs.given.values())
    # the variables: the fitted parameters with a variance, then the given inputs
    x = np.concatenate([theta[fit_params], [g.nominal for g in given]])
    steps = np.concatenate([STEP_IN_U * sd[fit_params],
                            [STEP_IN_U * g.standard_uncertainty if g.standard_uncertainty > 0 else 1e-8 * g.nominal
                             for g in given]])

    def evaluate(columns: np.ndarray) -> np.ndarray:
        thetas = np.repeat(theta[:, None], columns.shape[1], axis=1)
        thetas[fit_params] = columns[:fit_params.size]
        out = model.evaluate(thetas, {g.name: columns[fit_params.size + j] for j, g in enumerate(given)})
        return np.stack([out[q] for q in QUANTITIES])

    y0, grad = sensitivities(evaluate, x, steps, vectorised=True)   # one vectorised evaluation
    cov_fit = model.cov[np.ix_(fit_params, fit_params)]
    values, sensitivity, contributions, total = {}, {}, {}, {}
    for row, q in enumerate(QUANTITIES):
        values[q] = float(y0[row])
        g_fit = grad[row, :fit_params.size]
        fit_var = float(g_fit @ cov_fit @ g_fit)
        sensitivity[q], contributions[q] = {}, {FIT: float(np.sqrt(max(fit_var, 0.0)))}
        for j, g in enumerate(given):
            c = float(grad[row, fit_params.size + j])
            sensitivity[q][g.name] = c
            contributions[q][g.name] = abs(c) * g.standard_uncertainty
        total[q] = float(np.sqrt(sum(v * v for v in contributions[q].values())))
    return GumPropagation(values, sensitivity, contributions, total)
