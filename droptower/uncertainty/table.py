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
