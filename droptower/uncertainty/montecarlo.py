"""Propagation of distributions by Monte Carlo (JCGM 101:2008): draw the fit's parameters from
their normal distribution (mean θ̂, the fit's covariance) and each input from its own (normal,
or rectangular over x ± a), evaluate the extraction's closed forms on every trial (the fitted
decay is not fitted again, so a trial costs a few array operations), and read the standard
uncertainty and the probabilistically symmetric coverage interval off the trials.

The number of trials is adaptive (JCGM 101, 7.9): batches of ``batch`` trials until, for every
quantity, twice the standard deviation of the batch means of y, u(y) and the interval's ends
is within the numerical tolerance δ = ``tolerance`` · u(y).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from droptower.errors import DroptowerError, expects
from droptower.uncertainty.inputs import DropInputs, Input
from droptower.uncertainty.model import QUANTITIES, DropModel

#: trials per batch of the adaptive procedure (JCGM 101, 7.9.2: M = max(J, 10⁴))
BATCH = 10_000
#: the numerical tolerance δ as a share of u(y) (two significant digits of u, JCGM 101 7.9.2)
TOLERANCE = 0.02
#: at most this many trials, whatever the tolerance
MAX_TRIALS = 400_000


@dataclass(frozen=True)
class MonteCarloPropagation:
    """One drop's Monte Carlo result per quantity (SI): the trials' ``mean``, ``standard_uncertainty``,
    and the ``low``/``high`` ends of the ``coverage`` interval; ``trials`` drawn in all."""

    mean: dict[str, float]
    standard_uncertainty: dict[str, float]
    low: dict[str, float]
    high: dict[str, float]
    coverage: float
    trials: int


def draw_input(x: Input, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` draws of input ``x`` (normal with u, or rectangular over nominal ± √3·u; GUM 4.3.7)."""
    if x.distribution == "rectangular":
        return rng.uniform(x.nominal - x.half_width, x.nominal + x.half_width, n)
    return rng.normal(x.nominal, x.standard_uncertainty, n)


def draw_fit(theta: np.ndarray, cov: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` draws (7, n) of the fit's parameters from N(θ, cov); a singular covariance (an absent
    torque fit) is factored by its eigenvalues."""
    w, v = np.linalg.eigh(cov)
    root = v * np.sqrt(np.clip(w, 0.0, None))
    return theta[:, None] + root @ rng.standard_normal((theta.size, n))


@expects(model=DropModel, inputs=DropInputs)
def propagate_monte_carlo(model: DropModel, inputs: DropInputs, *, coverage: float = 0.95, batch: int = BATCH,
                          tolerance: float = TOLERANCE, max_trials: int = MAX_TRIALS,
                          seed: int = 0) -> MonteCarloPropagation:
    """Monte Carlo propagation of one drop's fit and inputs (JCGM 101, adaptive, 7.9).

    Parameters
    ----------
    model : DropModel
        The drop's measurement model.
    inputs : DropInputs
        The given inputs and their distributions.
    coverage : float
        Coverage probability of the interval (0.95).
    batch : int
        Trials per batch.
    tolerance : float
        Numerical tolerance as a share of each quantity's standard uncertainty.
    max_trials : int
        Stop after this many trials even if not yet stable.
    seed : int
        Seed of the random generator (the result is reproducible).

    Returns
    -------
    MonteCarloPropagation
        Mean, standard uncertainty and coverage interval per quantity, and the number of trials.
    """
    model.check_inputs(inputs.given)
    if not (isinstance(batch, int) and batch >= 2 and isinstance(max_trials, int) and tolerance > 0):
        raise DroptowerError(f"batch {batch!r} must be an int >= 2, max_trials {max_trials!r} an int and tolerance "
                             f"{tolerance!r} > 0", where="batch")
    rng = np.random.default_rng(seed)
    tail = 100 * (1 - coverage) / 2
    runs: list[dict[str, np.ndarray]] = []
    stats: list[np.ndarray] = []       # per batch: (quantity, [mean, u, low, high])
    while True:
        draws = {name: draw_input(x, batch, rng) for name, x in inputs.given.items()}
        out = model.evaluate(draw_fit(model.theta, model.cov, batch, rng), draws)
        runs.append(out)
        stats.append(np.array([[np.mean(out[q]), np.std(out[q], ddof=1), *np.percentile(out[q], [tail, 100 - tail])]
                               for q in QUANTITIES]))
        h = len(stats)
        if h >= 2:
            s = np.std(np.stack(stats), axis=0, ddof=1) / np.sqrt(h)       # JCGM 101, 7.9.4
            u = np.mean(np.stack(stats)[:, :, 1], axis=0)
            finite = np.isfinite(u) & (u > 0)
            if np.all(2 * s[finite] <= tolerance * u[finite, None]) or h * batch >= max_trials:
                break
    pooled = {q: np.concatenate([r[q] for r in runs]) for q in QUANTITIES}
    lows, highs = {}, {}
    for q, y in pooled.items():
        lows[q], highs[q] = (float(v) for v in np.percentile(y, [tail, 100 - tail]))
    return MonteCarloPropagation(mean={q: float(np.mean(y)) for q, y in pooled.items()},
                                 standard_uncertainty={q: float(np.std(y, ddof=1)) for q, y in pooled.items()},
                                 low=lows, high=highs, coverage=coverage, trials=len(runs) * batch)
