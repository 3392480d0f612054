"""Fit several model families to the same data and rank them: ``compare-models`` as a library call.

:func:`compare_models` fits every family (servo records: :func:`~droptower.identify.strategies.identify`,
the later families seeing the earlier results, so ``zerodim20`` starts from ``zerodim6``;
drop-test decays: :func:`~droptower.identify.dropfit.identify_drops` on the same fitting tests),
each within its own wall-time budget (:mod:`.budget`), and ranks them by one criterion: with a
hold-out (servo records kept out of every fit) by what each family predicts on it
(:data:`HOLDOUT_RULE`: a richer family earns its place on records it was not fitted to, not on
the fit), else by the information criterion on the fitting data
(:data:`~droptower.identify.criterion.RULE`). The table is always complete:

- a family whose data requirement the records do not meet (``overlay`` without steady sine
  blocks at several amplitudes and frequencies) is skipped with the reason (not a row);
- a family that does not converge (its optimiser's evaluation limit, or its time budget) is a
  row with ``status`` "not converged" (and the reason), ranked after every converged family;
- the others are ranked best first.

:meth:`Comparison.exit_code` is the command line's exit code: 0 when the best-ranked family
converged with a good fit (or ``accept_poor``), :data:`~droptower.identify.verdict.EXIT_POOR_FIT`
when it is a poor fit, :data:`EXIT_NONE_FITS` when no family converged.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np
import pandas as pd

from droptower.deprecation import renamed_keywords
from droptower.errors import DroptowerError, expects
from droptower.identify.budget import BudgetExceeded, now, time_budget
from droptower.identify.criterion import RULE

# the default budgets (each family's, all together), named once for the API and the command line
from droptower.fit_defaults import DEFAULT_BUDGET_S, DEFAULT_TOTAL_BUDGET_S  # noqa: E402
#: Hold-out errors within this many percentage points of each other are a tie (a tie goes to the
#: family with fewer parameters): a tenth of a percent of the largest load is below what the
#: repeats of a servo test agree to.
HOLDOUT_TIE_PERCENT = 0.1
#: How the ranking is made when a hold-out is given (printed with it).
HOLDOUT_RULE = (f"hold-out nRMSE: each family's RMS error on the hold-out records (fitted to none of them), in percent "
                f"of their largest load; lower is better; families within {HOLDOUT_TIE_PERCENT:g} percentage points of "
                "each other are tied and a tie goes to fewer parameters; bic and delta_bic on the fitting data are "
                "reported beside it; non-converged fits last")
#: Exit code when no family converged (as for a fit that does not converge: nothing usable).
EXIT_NONE_FITS = 2
CONVERGED, NOT_CONVERGED = "converged", "not converged"


@dataclass
class Comparison:
    """The result of :func:`compare_models`.

    ranking: one row per fitted family, best first (columns ``family``, ``status``,
    ``n_parameters``, the errors, ``bic``, ``delta_bic``, ``verdict``, ``wall_s``, ...);
    records: servo records only, the per-record error table (the zero-dimensional model paper,
    Fig. 8), else None; results: the identifications of the families that ended (converged or
    not) by name; skipped: family -> why its data requirement is not met; not_converged:
    family -> why it did not converge; budget_s: the budget (s) of each family's fit, or family
    -> its budget, as given (None: unbounded); drops: fitted to
    drop-test decays.
    """

    ranking: pd.DataFrame
    records: pd.DataFrame | None
    results: dict[str, Any]
    skipped: dict[str, str] = field(default_factory=dict)
    not_converged: dict[str, str] = field(default_factory=dict)
    budget_s: float | dict[str, float | None] | None = DEFAULT_BUDGET_S
    drops: bool = False
    rule: str = RULE

    @property
    def best(self) -> str | None:
        """The best-ranked family that converged (None: none did)."""
        ok = self.ranking[self.ranking["status"] == CONVERGED]
        return None if ok.empty else str(ok["family"].iloc[0])

    def exit_code(self, accept_poor: bool = False) -> int:
        """0: the best family converged with a good fit (or ``accept_poor``); 3: it is a poor fit;
        2: no family converged."""
        from droptower.identify.verdict import EXIT_POOR_FIT, POOR

        if self.best is None:
            return EXIT_NONE_FITS
        verdict = self.ranking.loc[self.ranking["family"] == self.best, "verdict"].iloc[0]
        return EXIT_POOR_FIT if verdict == POOR and not accept_poor else 0

    def to_frame(self) -> pd.DataFrame:
        """The ranking, one row per fitted family, best first."""
        return self.ranking.copy()

    def as_dict(self) -> dict[str, Any]:
        """Deprecated: :meth:`to_dict` (removed in the next release)."""
        from droptower.deprecation import warn_deprecated

        warn_deprecated("Comparison.as_dict()", "Comparison.to_dict()")
        return self.to_dict()

    def __repr__(self) -> str:
        return (f"<Comparison of {len(self.ranking)} famil{'ies' if len(self.ranking) != 1 else 'y'} on "
                f"{'drop tests' if self.drops else 'servo records'}: best {self.best}"
                + (f"; skipped {', '.join(self.skipped)}" if self.skipped else "")
                + (f"; not converged {', '.join(self.not_converged)}" if self.not_converged else "") + ">")

    def _repr_html_(self) -> str:
        return f"<p>{repr(self).strip('<>')}</p>" + self.ranking.to_html()

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: the rule, the ranking (and per-record table) as lists of rows, the skipped
        and non-converged families with their reasons, the budget."""
        import json

        out = {"ranking_rule": self.rule, "ranking": json.loads(self.ranking.to_json(orient="records")),
               "skipped": dict(self.skipped), "not_converged": dict(self.not_converged), "budget_s": self.budget_s}
        if self.records is not None:
            out["records"] = json.loads(self.records.to_json(orient="records"))
        return out


@renamed_keywords(kinds="families")
@expects(data=[("droptower.identify.data.Segment", "droptower.identify.droplogs.DropDecay")], families=["builtins.str"])
def compare_models(data: list, families: list[str], *, holdout: list | None = None,
                   budget_s: float | dict[str, float | None] | None = DEFAULT_BUDGET_S,
                   total_budget_s: float | None = DEFAULT_TOTAL_BUDGET_S, excluded: list[dict[str, str]] | None = None,
                   settings: Any = None, options: dict[str, dict[str, Any]] | None = None,
                   on_family: Callable[[str], None] | None = None,
                   on_skip: Callable[[str, str], None] | None = None) -> Comparison:
    """Fit every family of ``families`` to ``data`` and rank them (see the module docstring).

    Parameters
    ----------
    data : list of Segment or list of DropDecay
        Servo records (:class:`~droptower.identify.data.Segment`) or drop-test decays
        (:class:`~droptower.identify.droplogs.DropDecay`), not mixed.
    families : list of str
        Family names (``kinds`` in release 0.1: deprecated); they are fitted in the order of
        their number of parameters (the cheaper first, ties in the order given), so a budget
        runs out on the costliest.
    holdout : list of Segment, optional
        Servo records kept out of every fit: the families are ranked by their error on them
        (:data:`HOLDOUT_RULE`), the information criterion on the fitting data reported beside it.
    budget_s : float or dict, optional
        Wall-time budget of each family's fit in s (None: unbounded), or family -> its budget
        (a family not named gets :data:`DEFAULT_BUDGET_S`). A family over its budget is listed
        "not converged" and ranked last.
    total_budget_s : float, optional
        Wall-time budget of all the fits together in s (None: unbounded): each family gets at
        most an equal share of what is left of it when its fit starts (what a cheaper family
        leaves unused goes to the later ones), so the table is complete within it (plus at
        most one core call per family).
    excluded : list of dict, optional
        Drop tests: the tests left out when reading (reported).
    settings : DropFitSettings, optional
        Drop tests: the fit settings (:class:`~droptower.identify.dropfit.DropFitSettings`).
    options : dict, optional
        Family -> its options (e.g. ``{"template": {"template": "rapp2022_nr60"}}``).
    on_family : callable, optional
        Called with a family's name before its fit.
    on_skip : callable, optional
        Called with a family's name and the reason when it is skipped.

    Returns
    -------
    Comparison
        The ranking and what was skipped or did not converge.

    Raises
    ------
    DroptowerError
        No data, no family, or data that suit no family.
    """
    from droptower.identify.droplogs import DropDecay

    if not data:
        raise DroptowerError("compare_models: no data")
    if not families:
        raise DroptowerError("compare_models: no model family given")
    kinds = list(families)
    drops = isinstance(data[0], DropDecay)
    if any(isinstance(d, DropDecay) != drops for d in data):
        raise DroptowerError("compare_models: servo records and drop-test decays cannot be ranked together")
    options = options or {}
    stray = sorted(set(options) - set(kinds))
    if stray:  # options of a family not ranked would be silently ignored
        raise DroptowerError(f"compare_models: options given for {', '.join(stray)}, which is not among the families "
                             f"ranked ({', '.join(kinds)})")
    results: dict[str, Any] = {}
    skipped: dict[str, str] = {}
    over: dict[str, tuple[str, float]] = {}  # family -> (reason, seconds spent)
    if total_budget_s is not None and not total_budget_s > 0:
        raise DroptowerError(f"compare_models: total_budget_s must be positive, got {total_budget_s!r}")
    sizes = {kind: _n_parameters(kind, data, drops, options.get(kind)) for kind in kinds}
    kinds = sorted(kinds, key=lambda kind: sizes[kind])  # stable: ties keep the order given
    deadline = now() + (math.inf if total_budget_s is None else float(total_budget_s))
    for i, kind in enumerate(kinds):
        left = len(kinds) - i  # families not yet fitted, this one included
        if on_family is not None:
            on_family(kind)
        start = now()
        own = budget_s.get(kind, DEFAULT_BUDGET_S) if isinstance(budget_s, dict) else budget_s
        share = max((deadline - start) / left, 1e-3)  # an equal share of what is left (never 0: a budget is > 0)
        try:
            with time_budget(share if own is None or share < own else own):
                results[kind] = _fit(kind, data, drops, holdout, results, excluded, settings, options.get(kind))
        except BudgetExceeded as exc:
            over[kind] = (str(exc), now() - start)
            continue
        except DroptowerError as exc:  # the data do not suit the family (its data requirement)
            skipped[kind] = exc.message
            if on_skip is not None:
                on_skip(kind, exc.message)
            continue
        if not drops:
            results[kind].wall_s = now() - start
    if not results and not over:
        raise DroptowerError(f"no model family could be fitted to these "
                             f"{'drop tests' if drops else 'records'} ({'; '.join(f'{k}: {v}' for k, v in skipped.items())})")
    ranking, records = _tables(results, data, holdout, drops)
    not_converged = {k: "the optimiser did not converge (its evaluation limit)"
                     for k, r in results.items() if not r.converged}
    rows = []
    for kind, (reason, seconds) in over.items():
        not_converged[kind] = reason
        rows.append({"family": kind, "n_parameters": sizes[kind],
                     "bic": math.nan, "verdict": NOT_CONVERGED, "wall_s": seconds, "converged": False})
    by_holdout = bool(holdout) and not drops and not ranking.empty
    if by_holdout:
        ranking = by_holdout_error(ranking)
    ranking = _complete(ranking, rows, not_converged)
    return Comparison(ranking, records, results, skipped, not_converged, budget_s, drops,
                      HOLDOUT_RULE if by_holdout else RULE)


def by_holdout_error(ranking: pd.DataFrame, tie: float = HOLDOUT_TIE_PERCENT) -> pd.DataFrame:
    """``ranking`` (columns ``family``, ``n_parameters``, ``holdout_nrmse_percent``, ``converged``)
    re-ordered best first by the hold-out error (:data:`HOLDOUT_RULE`): the converged families
    by their hold-out nRMSE (%), errors within ``tie`` percentage points of the best remaining
    one a group ordered by parameters, then the others in the same way; numbered from 1."""
    from droptower.identify.criterion import order

    names = [m for ok in (True, False) for m in order(
        [(m, int(k), float(e) if np.isfinite(e) else math.inf) for m, k, e, c in
         zip(ranking["family"], ranking["n_parameters"], ranking["holdout_nrmse_percent"], ranking["converged"])
         if bool(c) == ok], tie)]
    table = ranking.set_index("family").loc[names].reset_index()
    table.index = np.arange(1, len(table) + 1)
    return table


def _fit(kind: str, data: list, drops: bool, holdout: list | None, results: dict[str, Any],
         excluded: list[dict[str, str]] | None, settings: Any, options: dict[str, Any] | None) -> Any:
    if drops:
        from droptower.identify.dropfit import DropFitSettings, identify_drops

        return identify_drops(kind, data, excluded=excluded, settings=settings or DropFitSettings(), options=options)
    from droptower.identify.strategies import identify

    return identify(kind, data, holdout=holdout, previous=results, options=options)


def _tables(results: dict[str, Any], data: list, holdout: list | None,
            drops: bool) -> tuple[pd.DataFrame, pd.DataFrame | None]:
    from droptower.identify.report import drop_ranking_table, ranking_table, record_table

    if not results:
        return pd.DataFrame(), (None if drops else pd.DataFrame())
    if drops:
        return drop_ranking_table(results), None
    return ranking_table(results, data), record_table(results, data + (holdout or []))


def _n_parameters(kind: str, data: list, drops: bool, options: dict[str, Any] | None) -> int:
    """The family's number of parameters (for the row of a family that ran out of time)."""
    from droptower.identify.data import DataScale
    from droptower.identify.families import family_class

    if drops:
        from droptower.identify.dropfit import drop_scale

        scale = drop_scale(data)
    else:
        scale = DataScale.of(data)
    try:
        return len(family_class(kind)(scale, options).parameters)
    except DroptowerError:
        return 0


def _complete(ranking: pd.DataFrame, rows: list[dict[str, Any]], not_converged: dict[str, str]) -> pd.DataFrame:
    """The ranking with a ``status`` column (after ``family``) and the families that ran out of
    time appended (ranked last, their scores NaN), numbered from 1."""
    table = pd.concat([ranking, pd.DataFrame(rows)], ignore_index=True) if rows else ranking.reset_index(drop=True)
    if "delta_bic" in table.columns:
        table["delta_bic"] = table["delta_bic"].astype(float)
    for key in ("noise_floor_nm", "noise_allowance_rad", "n_eff"):
        if key in table.columns and rows:
            table[key] = table[key].ffill()
    status = [CONVERGED if bool(c) else NOT_CONVERGED for c in table["converged"]]
    table.insert(1, "status", status)
    table["note"] = [not_converged.get(m, "") for m in table["family"]]
    table.index = np.arange(1, len(table) + 1)
    return table
