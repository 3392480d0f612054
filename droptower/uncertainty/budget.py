"""One drop's uncertainty budget: every per-drop quantity with its combined standard uncertainty,
its expanded uncertainty and the contribution of each input and of the fit (GUM, JCGM 100:2008;
Monte Carlo, JCGM 101:2008; docs/guide/uncertainty.md).

Which method gives the result (``method="auto"``): both run, and the GUM's interval y ± 2·u_c
is validated against the Monte Carlo coverage interval as JCGM 101, 8 prescribes: the GUM is
adequate when both ends of its interval of the same coverage probability (y ± 1.96·u_c for 95 %),
and u_c itself, agree within :data:`GUM_TOLERANCE` of u_c. Then the
result is the GUM's (U = k·u_c, k = 2); otherwise the Monte Carlo's (u from the trials, the 95 %
interval from their quantiles, U95 its half-width). The GUM fails where the model is non-linear
over the spread (the damping ratio ½(e^(4πδ/ω) − 1) at a large relative uncertainty of δ) or the
output is not near normal (one rectangular input dominating: its 95 % interval is ±1.65·u, not
±2·u). The budget's terms are always the first-order ones (|c_i|·u(x_i)).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from collections.abc import Mapping
from typing import Any, Literal

import numpy as np
import pandas as pd
from scipy.special import erfinv

from droptower.errors import DroptowerError, expects
from droptower.extract.result import ExtractionResult
from droptower.rig.uncertainty import RigUncertainty
from droptower.units import GRAVITY_M_PER_S2
from droptower.uncertainty.gum import propagate_gum
from droptower.uncertainty.inputs import DropInputs, drop_inputs
from droptower.uncertainty.model import QUANTITIES, DropModel
from droptower.uncertainty.montecarlo import TOLERANCE, propagate_monte_carlo

#: the GUM is adequate when its interval's ends and u_c agree with Monte Carlo's within this share of u_c
GUM_TOLERANCE = 0.05
#: coverage factor of the GUM's expanded uncertainty (~95 % for a near-normal output, GUM 6.3)
COVERAGE_FACTOR = 2.0


@dataclass(frozen=True)
class QuantityUncertainty:
    """One quantity of one drop (SI, as the :class:`~droptower.extract.ExtractionResult` field
    ``name``): its ``value``; ``standard_uncertainty`` u and ``expanded_uncertainty`` U95 (k = 2,
    or the Monte Carlo interval's half-width); the 95 % interval ``low``–``high``; the ``method``
    that gave them (``"GUM"`` or ``"MC"``); both methods' u (NaN where one did not run); and
    ``contributions`` source -> u_i(y) (each given input's and the fit's, first order)."""

    name: str
    value: float
    standard_uncertainty: float
    expanded_uncertainty: float
    low: float
    high: float
    method: Literal["GUM", "MC"]
    gum_standard_uncertainty: float
    mc_standard_uncertainty: float
    contributions: dict[str, float]

    @property
    def dominant(self) -> str:
        """The source with the largest contribution (an input's name or ``"fit"``); "" if none."""
        positive = {k: v for k, v in self.contributions.items() if v > 0}
        return max(positive, key=positive.get) if positive else ""


@dataclass(frozen=True)
class DropBudget:
    """Every quantity of one drop (:data:`~droptower.uncertainty.model.QUANTITIES`) with its
    uncertainty; ``inputs`` the given inputs and those not given; ``trials`` of Monte Carlo (0: none)."""

    quantities: dict[str, QuantityUncertainty]
    inputs: DropInputs
    trials: int

    def __getitem__(self, name: str) -> QuantityUncertainty:
        return self.quantities[name]

    def table(self) -> pd.DataFrame:
        """The budget as a table: one row per quantity and source, with ``contribution`` u_i(y)
        (SI, the quantity's unit) and ``share_pct`` (u_i²/u_c², %, first order)."""
        rows = []
        for q in self.quantities.values():
            total = sum(v * v for v in q.contributions.values())
            for source, c in q.contributions.items():
                rows.append({"quantity": q.name, "source": source, "contribution": c,
                             "share_pct": 100 * c * c / total if total > 0 else math.nan})
        return pd.DataFrame(rows, columns=["quantity", "source", "contribution", "share_pct"])


def coverage_factor(coverage: float) -> float:
    """k_p of a normal output for the coverage probability ``coverage`` in (0, 1) (1.96 for 0.95; GUM G.1.3)."""
    if not (isinstance(coverage, (int, float)) and not isinstance(coverage, bool) and 0 < coverage < 1):
        raise DroptowerError(f"must be a probability between 0 and 1, got {coverage!r}", where="coverage")
    return float(np.sqrt(2.0) * erfinv(coverage))


def _nominal(name: str, given: float | None, metadata: Mapping[str, Any], rig_value: float | None) -> float | None:
    if given is not None:
        return float(given)
    value = metadata.get(name)
    try:
        return float(value) if value is not None else rig_value
    except (TypeError, ValueError):
        raise DroptowerError(f"the log's {name} {value!r} is not a number", where=name) from None


@expects(result="droptower.extract.result.ExtractionResult", uncertainty=(RigUncertainty, type(None)),
         rig=("droptower.rig.config.RigConfig", type(None)), metadata=(Mapping, type(None)))
def drop_budget(result: ExtractionResult, uncertainty: RigUncertainty | None = None, *, rig: Any = None,
                metadata: Mapping[str, Any] | None = None, lever_length_m: float | None = None,
                laser_radius_m: float | None = None, drop_mass_kg: float | None = None,
                drop_height_m: float | None = None, restitution: float | None = None,
                method: Literal["auto", "gum", "mc"] = "auto", coverage: float = 0.95,
                tolerance: float = TOLERANCE, seed: int = 0) -> DropBudget:
    """The uncertainty budget of one drop.

    Parameters
    ----------
    result : ExtractionResult
        The drop's extraction (with its fits, as :func:`droptower.extract.extract` returns it).
    uncertainty : RigUncertainty, optional
        The rig's input uncertainties; default ``rig.uncertainty``; none: only the fit's.
    rig : RigConfig, optional
        The rig: nominal lever length, laser radius, restitution and gravity where neither the
        arguments nor ``metadata`` give them.
    metadata : mapping, optional
        The log's metadata (``DropSignals.metadata``): ``lever_length_m``, ``laser_radius_m``,
        ``drop_mass_kg``, ``drop_height_m``, ``restitution``.
    lever_length_m, laser_radius_m, drop_mass_kg, drop_height_m : float, optional
        Nominal values (m, m, kg, m) over the metadata's.
    restitution : float, optional
        The contact's restitution (impact-law energy), over the metadata's.
    method : {"auto", "gum", "mc"}
        ``"auto"``: both, the GUM where Monte Carlo validates it (JCGM 101, 8), else Monte Carlo;
        ``"gum"``: the law of propagation only (fast, k = 2); ``"mc"``: Monte Carlo only.
    coverage : float
        Coverage probability of the Monte Carlo interval (0.95; the GUM's k = 2 is ~95 %).
    tolerance : float
        Monte Carlo's numerical tolerance, as a share of u.
    seed : int
        Seed of the Monte Carlo draws.

    Returns
    -------
    DropBudget
        Per quantity: value, u, U95, interval, method and the contributions of the inputs and the fit.

    Raises
    ------
    DroptowerError
        An uncertainty is given for an input whose nominal value is unknown, or ``method`` is unknown.
    """
    if method not in ("auto", "gum", "mc"):
        raise DroptowerError(f"must be 'auto', 'gum' or 'mc', got {method!r}", where="method")
    metadata = metadata or {}
    coverage_factor(coverage)  # a probability, checked before anything runs
    if uncertainty is None and rig is not None:
        uncertainty = rig.uncertainty
    lever = _nominal("lever_length_m", lever_length_m, metadata, getattr(rig, "lever_length_m", None))
    radius = _nominal("laser_radius_m", laser_radius_m, metadata,
                      rig.sensors.laser.radius_m if rig is not None else None)
    mass = _nominal("drop_mass_kg", drop_mass_kg, metadata, None)
    height = _nominal("drop_height_m", drop_height_m, metadata, None)
    k = _nominal("restitution", restitution, metadata, getattr(rig, "restitution", None))
    model = DropModel.from_result(result, lever_length_m=lever, laser_radius_m=radius, drop_mass_kg=mass,
                                  drop_height_m=height, restitution=k,
                                  gravity_m_per_s2=getattr(rig, "gravity_m_per_s2", GRAVITY_M_PER_S2))
    inputs = drop_inputs(uncertainty, inertia_kgm2=result.inertia_kgm2, lever_length_m=model.nominal.get("lever_length_m"),
                         laser_radius_m=radius, drop_mass_kg=mass, drop_height_m=height,
                         sample_rate_hz=result.sample_rate_hz)
    gum = propagate_gum(model, inputs)
    mc = propagate_monte_carlo(model, inputs, coverage=coverage, tolerance=tolerance, seed=seed) \
        if method != "gum" else None
    out = {}
    for q in QUANTITIES:
        y, u = gum.values[q], gum.standard_uncertainty[q]
        use_gum = method == "gum"
        if method == "auto":
            use_gum = _gum_validated(y, u, mc.low[q], mc.high[q], mc.standard_uncertainty[q], coverage)
        if use_gum:
            big_u = COVERAGE_FACTOR * u
            low, high, chosen = y - big_u, y + big_u, "GUM"
        else:
            u, low, high, chosen = mc.standard_uncertainty[q], mc.low[q], mc.high[q], "MC"
            big_u = (high - low) / 2
        out[q] = QuantityUncertainty(q, y, u, big_u, low, high, chosen, gum.standard_uncertainty[q],
                                     mc.standard_uncertainty[q] if mc else math.nan, gum.contributions[q])
    return DropBudget(out, inputs, mc.trials if mc else 0)


def _gum_validated(y: float, u: float, low: float, high: float, u_mc: float, coverage: float) -> bool:
    """JCGM 101, 8.2: the GUM's interval of the same coverage probability, y ± k_p·u_c with k_p
    of the normal distribution (1.96 for 95 %; the reported U keeps the conventional k = 2), has
    its ends within the tolerance of Monte Carlo's, and u_c is Monte Carlo's within it too."""
    if not np.isfinite(y) or not u > 0:
        return True  # nothing to validate: no value, or an exact one
    tol = GUM_TOLERANCE * u
    big_u = coverage_factor(coverage) * u
    return bool(abs(y - big_u - low) <= tol and abs(y + big_u - high) <= tol and abs(u_mc - u) <= tol)
