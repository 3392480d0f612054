"""The GUM's law of propagation of uncertainty (JCGM 100:2008, 5.1.2) on a drop's measurement
model: sensitivity coefficients c_i = ∂f/∂x_i by central differences through the extraction's
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
from droptower.uncertainty.inputs import DropInputs
from droptower.uncertainty.model import QUANTITIES, DropModel

#: central-difference step, in standard uncertainties of the input (the linearisation on the
#: scale of the uncertainty itself, as droptower.extract.uncertainty.propagate does)
STEP_IN_U = 1e-3

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
    # one vectorised evaluation: the centre, then ± steps in each fitted parameter and each input
    n = 1 + 2 * fit_params.size + 2 * len(given)
    thetas = np.repeat(theta[:, None], n, axis=1)
    columns = {x.name: np.full(n, x.nominal) for x in given}
    col = 1
    for i in fit_params:
        thetas[i, col], thetas[i, col + 1] = theta[i] + STEP_IN_U * sd[i], theta[i] - STEP_IN_U * sd[i]
        col += 2
    for x in given:
        h = STEP_IN_U * x.standard_uncertainty if x.standard_uncertainty > 0 else 1e-8 * x.nominal
        columns[x.name][col], columns[x.name][col + 1] = x.nominal + h, x.nominal - h
        col += 2
    out = model.evaluate(thetas, columns)
    values, sensitivity, contributions, total = {}, {}, {}, {}
    for q in QUANTITIES:
        y = out[q]
        values[q] = float(y[0])
        grad = np.zeros(theta.size)
        col = 1
        for i in fit_params:
            grad[i] = (y[col] - y[col + 1]) / (2 * STEP_IN_U * sd[i])
            col += 2
        fit_var = float(grad @ model.cov @ grad)
        sensitivity[q], contributions[q] = {}, {FIT: float(np.sqrt(max(fit_var, 0.0)))}
        for x in given:
            h = STEP_IN_U * x.standard_uncertainty if x.standard_uncertainty > 0 else 1e-8 * x.nominal
            c = float((y[col] - y[col + 1]) / (2 * h))
            sensitivity[q][x.name] = c
            contributions[q][x.name] = abs(c) * x.standard_uncertainty
            col += 2
        total[q] = float(np.sqrt(sum(v * v for v in contributions[q].values())))
    return GumPropagation(values, sensitivity, contributions, total)
