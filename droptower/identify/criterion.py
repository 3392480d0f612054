"""One criterion to rank model families fitted to the same data (Schwarz 1978; Kass & Raftery 1995).

Every family is scored on the SAME samples with the same Gaussian noise model:

    BIC = n_eff ln(RSS / (n sigma^2)) + k ln(n_eff)

RSS: the family's sum of squared errors over the n compared samples; sigma: the data's noise
floor (:mod:`.noise`, estimated without any model), which makes the score unit-free (the
torque's unit cancels); n_eff: ONE effective sample size for all families, from the noise's
own lag-1 correlation (n_eff = n for white noise), never from a family's residual, whose
correlation grows with a systematic misfit; k: the family's number of fitted parameters. A
family with more parameters ranks higher only when its error falls by more than its
parameters cost. Differences below :data:`TIE` (Kass & Raftery's "not worth more than a
bare mention") are a tie, and a tie goes to the family with fewer parameters.
"""
from __future__ import annotations

import math

import numpy as np

#: BIC differences up to this are a tie (Kass & Raftery 1995: 0-2 "not worth more than a bare mention").
TIE = 2.0

#: How the ranking is made (printed with it).
RULE = ("BIC = n_eff ln(RSS / (n sigma^2)) + k ln(n_eff) on the same n fitting samples for every family "
        "(RSS: the family's squared error; sigma: the data's noise floor, estimated without a model; n_eff: one "
        "effective sample size from the noise's lag-1 correlation; k: fitted parameters); lower is better; "
        f"families within {TIE:g} of each other are tied and a tie goes to fewer parameters; delta_bic > 10: "
        "strong evidence against the family; non-converged fits last")


def bic(rss: float, n_samples: int, n_eff: float, sigma: float, n_parameters: int) -> float:
    """The criterion of :data:`RULE` (dimensionless): rss and sigma^2 in the same unit."""
    mse = max(rss, 1e-300) / max(n_samples, 1)
    return n_eff * math.log(mse / max(sigma, 1e-300) ** 2) + n_parameters * math.log(max(n_eff, 1.0))


def order(scores: list[tuple[str, int, float]], tie: float = TIE) -> list[str]:
    """Names ranked best first from (name, n_parameters, bic): repeatedly, the families within
    ``tie`` of the best remaining one form a group, ordered by parameters, then by score."""
    rest = sorted(scores, key=lambda s: s[2])
    out: list[str] = []
    while rest:
        best = rest[0][2]
        group = [s for s in rest if s[2] <= best + tie or not np.isfinite(best)]
        out += [s[0] for s in sorted(group, key=lambda s: (s[1], s[2]))]
        rest = [s for s in rest if s not in group]
    return out
