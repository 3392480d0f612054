"""Per-drop result tables with their uncertainties: ``<output>_u`` (standard), ``<output>_U95``
(expanded, 95 %) and ``<output>_dominant`` (the budget's largest term) beside each output of
:data:`droptower.extract.result.OUTPUTS` that a budget covers, in the output's own unit
(``stiffness_nm_per_deg_u`` in N·m/deg), and ``uncertainty_not_given``: the inputs whose
uncertainty the rig did not state (left out of u, not counted as zero)."""
from __future__ import annotations

from typing import Any, Iterable, Literal, Mapping, Sequence

import numpy as np
import pandas as pd

from droptower.errors import DroptowerError, expects
from droptower.extract.result import OUTPUTS, ExtractionResult
from droptower.rig.uncertainty import RigUncertainty
from droptower.uncertainty.budget import DropBudget, drop_budget
from droptower.uncertainty.model import QUANTITIES
from droptower.uncertainty.montecarlo import TOLERANCE

#: the table's output names that carry an uncertainty: output name -> (SI quantity, factor)
UNCERTAIN_OUTPUTS: dict[str, tuple[str, float]] = {name: (attr, abs(factor)) for name, (attr, factor) in OUTPUTS.items()
                                                   if attr in QUANTITIES}


@expects(budget=(DropBudget, type(None)))
def uncertainty_columns(budget: DropBudget | None) -> dict[str, Any]:
    """The uncertainty columns of one drop (NaN and "" for a drop without a budget)."""
    row: dict[str, Any] = {}
    for name, (attr, factor) in UNCERTAIN_OUTPUTS.items():
        q = budget.quantities[attr] if budget is not None else None
        row[f"{name}_u"] = q.standard_uncertainty * factor if q else np.nan
        row[f"{name}_U95"] = q.expanded_uncertainty * factor if q else np.nan
        row[f"{name}_dominant"] = q.dominant if q else ""
    row["uncertainty_not_given"] = ";".join(budget.inputs.not_given) if budget is not None else ""
    return row


@expects(table=pd.DataFrame, budgets=[(DropBudget, type(None))])
def with_uncertainty(table: pd.DataFrame, budgets: Sequence[DropBudget | None]) -> pd.DataFrame:
    """A copy of the per-drop ``table`` (``extract`` rows, :func:`droptower.extract.result_row`)
    with the uncertainty columns of :func:`uncertainty_columns`, one budget per row in order
    (None: a drop that has none, e.g. its extraction failed).

    Parameters
    ----------
    table : pandas.DataFrame
        One row per drop.
    budgets : sequence of DropBudget or None
        The rows' budgets (:func:`drop_budgets`), as many as rows.

    Returns
    -------
    pandas.DataFrame
        The table with ``<output>_u``, ``<output>_U95``, ``<output>_dominant`` and ``uncertainty_not_given``.
    """
    if len(budgets) != len(table):
        raise DroptowerError(f"{len(budgets)} budgets for {len(table)} rows", where="budgets")
    extra = pd.DataFrame([uncertainty_columns(b) for b in budgets], index=table.index)
    return pd.concat([table.drop(columns=[c for c in extra.columns if c in table.columns]), extra], axis=1)


def drop_budgets(results: Iterable[ExtractionResult | None], uncertainty: RigUncertainty | None = None, *,
                 metadata: Iterable[Mapping[str, Any]] | None = None, rig: Any = None,
                 method: Literal["auto", "gum", "mc"] = "auto", tolerance: float = TOLERANCE,
                 seed: int = 0) -> list[DropBudget | None]:
    """The budget of every drop (:func:`~droptower.uncertainty.budget.drop_budget`), None for a
    missing result; ``metadata`` the logs' metadata in the same order (``DropSignals.metadata``),
    ``rig`` the nominal values the logs do not carry; ``method`` and ``tolerance`` as there;
    drop i draws with seed ``seed + i``."""
    results = list(results)
    metas = list(metadata) if metadata is not None else [{}] * len(results)
    if len(metas) != len(results):
        raise DroptowerError(f"{len(metas)} metadata for {len(results)} results", where="metadata")
    return [drop_budget(r, uncertainty, rig=rig, metadata=m, method=method, tolerance=tolerance, seed=seed + i)
            if r is not None else None
            for i, (r, m) in enumerate(zip(results, metas))]


def campaign_budgets(results: Iterable[ExtractionResult | None], uncertainty: RigUncertainty | None = None, *,
                     conditions: Iterable[Any] | None = None, metadata: Iterable[Mapping[str, Any]] | None = None,
                     rig: Any = None, tolerance: float = TOLERANCE, seed: int = 0) -> list[DropBudget | None]:
    """The budget of every drop of a campaign at a fraction of Monte Carlo's cost on each drop.

    Every drop gets the GUM (cheap). Monte Carlo runs only on *reference* drops (both methods,
    ``method="auto"``: the GUM where Monte Carlo validates it, JCGM 101, 8); a drop takes a
    reference's verdicts when its budget has the same make-up, for every quantity: each
    source's share u_i/u_c within :data:`~droptower.uncertainty.budget.GUM_TOLERANCE` of the
    reference's, and a relative uncertainty u_c/|y| at most :data:`MAKE_UP_SIZE` times the
    reference's (a model's curvature over the spread grows with it). Where the reference's GUM
    was validated, the drop's GUM stands; where it was not (its output's shape, e.g. a
    rectangular input dominating), the reference's Monte Carlo result is scaled to the drop (u
    and the interval's ends relative to the GUM's u). A drop matching no reference becomes one.
    ``conditions`` (one hashable key per drop, e.g. fixture, mass and height) says which
    reference to try first; ``metadata``, ``rig``, ``tolerance`` and ``seed`` as :func:`drop_budgets`.
    """
    from dataclasses import replace

    results = list(results)
    keys = list(conditions) if conditions is not None else [None] * len(results)
    metas = list(metadata) if metadata is not None else [{}] * len(results)
    if not (len(keys) == len(metas) == len(results)):
        raise DroptowerError(f"{len(results)} results, {len(keys)} conditions and {len(metas)} metadata", where="conditions")
    references: list[DropBudget] = []
    first: dict[Any, DropBudget] = {}
    out: list[DropBudget | None] = []
    for i, (r, key, m) in enumerate(zip(results, keys, metas)):
        if r is None:
            out.append(None)
            continue
        gum = drop_budget(r, uncertainty, rig=rig, metadata=m, method="gum")
        tried = ([first[key]] if key in first else []) + [ref for ref in references if ref is not first.get(key)]
        ref = next((ref for ref in tried if _same_make_up(ref, gum)), None)
        if ref is None:
            budget = drop_budget(r, uncertainty, rig=rig, metadata=m, method="auto", tolerance=tolerance, seed=seed + i)
            references.append(budget)
            first.setdefault(key, budget)
            out.append(budget)
            continue
        quantities = dict(gum.quantities)
        for name, q_ref in ref.quantities.items():
            if q_ref.method != "MC":
                continue
            q = quantities[name]
            scale = q.standard_uncertainty / q_ref.gum_standard_uncertainty
            quantities[name] = replace(q, standard_uncertainty=q_ref.mc_standard_uncertainty * scale,
                                       expanded_uncertainty=q_ref.expanded_uncertainty * scale,
                                       low=q.value - (q_ref.value - q_ref.low) * scale,
                                       high=q.value + (q_ref.high - q_ref.value) * scale, method="MC",
                                       mc_standard_uncertainty=q_ref.mc_standard_uncertainty * scale)
        out.append(DropBudget(quantities, gum.inputs, 0))
    return out


#: a drop's relative uncertainty may be at most this many times its reference's (:func:`campaign_budgets`)
MAKE_UP_SIZE = 1.25


def _same_make_up(ref: DropBudget, gum: DropBudget) -> bool:
    """Every quantity of ``gum`` has the make-up of ``ref``'s (:func:`campaign_budgets`)."""
    from droptower.uncertainty.budget import GUM_TOLERANCE

    if set(ref.inputs.given) != set(gum.inputs.given):
        return False
    for name, a in ref.quantities.items():
        b = gum.quantities[name]
        ua, ub = a.gum_standard_uncertainty, b.gum_standard_uncertainty
        if not (np.isfinite(ub) and np.isfinite(b.value)):
            if np.isfinite(ua) and np.isfinite(a.value):
                return False
            continue
        if ua == 0 or ub == 0:
            if ua != ub:
                return False
            continue
        if abs(ub / b.value) > MAKE_UP_SIZE * abs(ua / a.value) or set(a.contributions) != set(b.contributions):
            return False
        if any(abs(a.contributions[k] / ua - b.contributions[k] / ub) > GUM_TOLERANCE for k in a.contributions):
            return False
    return True
