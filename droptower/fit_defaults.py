"""The identification's defaults, named once: the time budgets of ranking families and the
share of a drop campaign held out of the fit.

A module of its own (no imports), as :mod:`droptower.rates`, so that the command line shows
them as its defaults without loading the identification (its help stays fast);
:mod:`droptower.identify.ranking` and :mod:`droptower.identify.dropfit` use them.
"""
from __future__ import annotations

__all__ = ["DEFAULT_BUDGET_S", "DEFAULT_TOTAL_BUDGET_S", "HOLDOUT_FRACTION"]

#: s: default wall-time budget of each family's fit when families are ranked
DEFAULT_BUDGET_S = 60.0
#: s: default wall-time budget of all the families' fits together: 120 s for the whole table,
#: less a margin for the one core call a family may run past its budget (droptower.identify.budget)
DEFAULT_TOTAL_BUDGET_S = 110.0
#: share of a drop campaign's tests held out of the fit and predicted (spread over inertias and
#: amplitudes, droptower.identify.dropfit.holdout_split)
HOLDOUT_FRACTION = 0.2
