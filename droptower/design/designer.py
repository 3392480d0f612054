"""``design``: from the region an engineer wants measured (or a model to identify) to a test plan.

One call from the target (amplitude and frequency ranges, preloads) to the designed campaign:
the rig's and coupling's files read, the preloads checked against the rig, the repeats chosen
for a target uncertainty from a virtual pilot test per condition (:mod:`.repeats`), or the
D-optimal drops that identify a model best (:mod:`.identification`). The result writes the
plan (:meth:`~droptower.design.choose.Design.write`) and converts to a table or a dict.
``droptower design`` is a thin layer over it.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Callable

from droptower.configs import DEFAULT_COUPLING, DEFAULT_RIG
from droptower.design.choose import Design, design_campaign
from droptower.design.coverage import Target
from droptower.design.identification import IdentificationDesign
from droptower.errors import DroptowerError

#: The range ``for_identification`` chooses from when no target is given: all the rig can do.
ALL_AMPLITUDES_DEG = (1e-3, 90.0)
ALL_FREQUENCIES_HZ = (0.1, 1000.0)
#: Drops of a design for identification when no budget is given.
IDENTIFICATION_TESTS = 12
#: Repeats per condition when neither ``repeats`` nor ``uncertainty_pct`` is given.
DEFAULT_REPEATS = 3


def design(amplitude_deg: tuple[float, float] | None = None, frequency_hz: tuple[float, float] | None = None, *,
           preloads_nm: tuple[float, ...] = (0.0,), repeats: int | None = None, uncertainty_pct: float | None = None,
           rig: str | Path = DEFAULT_RIG, coupling: str | Path = DEFAULT_COUPLING, max_tests: int | None = None,
           for_identification: str | None = None,
           on_note: Callable[[str], None] | None = None, uncertainty: Any = None) -> Design | IdentificationDesign:
    """Design a campaign that covers a target region, or that identifies a model best.

    Parameters
    ----------
    amplitude_deg : (float, float), optional
        The target amplitude range (low, high) in deg (required unless ``for_identification``;
        with it, the range the drops are chosen from, default all the rig can do).
    frequency_hz : (float, float), optional
        The target frequency range (low, high) in Hz (as ``amplitude_deg``).
    preloads_nm : tuple of float
        Preloads every condition is tested at (N*m).
    repeats : int, optional
        Repeats per condition (default 3; or ``uncertainty_pct``).
    uncertainty_pct : float, optional
        Instead of ``repeats``: enough repeats for this standard uncertainty (% of the value) of
        the mean stiffness and damping ratio of every condition, from a virtual pilot test per
        condition, with the rig's input uncertainties (its ``[uncertainty]``: J does not average
        out) counted; where an input alone exceeds the target, ``on_note`` says so.
    rig : str or path
        Rig TOML file or shipped preset name.
    coupling : str or path
        Coupling TOML file or shipped preset name (what the drops are predicted on).
    max_tests : int, optional
        The budget of drops (repeats, then the amplitude spacing give way to it); for
        identification the number of drops (default 12).
    for_identification : str, optional
        A drop-test model family (``template``: the coupling's own structure): the D-optimal
        drops that identify it, with the parameters' predicted standard errors.
    on_note : callable, optional
        Called with a line on what is being done (the pilot tests).
    uncertainty : RigUncertainty, optional
        With ``uncertainty_pct``: the rig's input uncertainties whose share repeats do not
        reduce (default: the rig file's ``[uncertainty]``).

    Returns
    -------
    Design or IdentificationDesign
        The conditions (``to_frame()``), coverage or predicted standard errors; ``write()``
        writes the plan TOML and the lab's run sheet.

    Examples
    --------
    >>> plan = design((0.3, 3.0), (22.0, 50.0), preloads_nm=(0.0, 500.0))  # doctest: +SKIP
    >>> plan.write("plan.toml", sheet="run_order.xlsx")  # doctest: +SKIP
    """
    from droptower.rheology import load_coupling
    from droptower.rig.config import load_rig

    if repeats is not None and uncertainty_pct is not None:
        raise DroptowerError("give `repeats` or `uncertainty_pct`, not both", where="uncertainty_pct")
    if uncertainty_pct is not None and not (math.isfinite(uncertainty_pct) and uncertainty_pct > 0):
        raise DroptowerError(f"must be a positive number, got {uncertainty_pct:g}", where="uncertainty_pct")
    if for_identification is None:
        for name, value in (("amplitude_deg", amplitude_deg), ("frequency_hz", frequency_hz)):
            if value is None:
                raise DroptowerError("the target region is required (or `for_identification`)", where=name)
    target = Target(tuple(amplitude_deg or ALL_AMPLITUDES_DEG), tuple(frequency_hz or ALL_FREQUENCIES_HZ),
                    tuple(float(p) for p in preloads_nm))
    rig_cfg = load_rig(rig)
    lo, hi = rig_cfg.preload_range_nm
    for p in target.preloads_nm:
        if not lo <= p <= hi:
            raise DroptowerError(f"preload {p:g} N*m is outside the range {lo:g}-{hi:g} N*m of rig {rig_cfg.name}",
                                 where="preloads_nm")
    coupling_model = load_coupling(coupling)
    if for_identification is not None:
        from droptower.design.identification import design_for_identification

        result = design_for_identification(rig_cfg, coupling_model, target, for_identification,
                                           max_tests or IDENTIFICATION_TESTS)
    else:
        result = design_campaign(rig_cfg, coupling_model, target, repeats=repeats or DEFAULT_REPEATS,
                                 max_tests=max_tests)
        if uncertainty_pct is not None:
            from droptower.design.repeats import pilot_uncertainty, repeats_advice

            if on_note is not None:
                on_note(f"pilot: one virtual test per condition ({result.n_conditions}) for the scatter of c and d")
            advice = repeats_advice(pilot_uncertainty(result, rig, coupling), uncertainty_pct,
                                    uncertainty if uncertainty is not None else rig_cfg.uncertainty)
            if not advice.reachable and on_note is not None:
                on_note(f"warning: {advice.limit}")
            n = advice.repeats
            result = design_campaign(rig_cfg, coupling_model, target, repeats=n, max_tests=max_tests,
                                     candidates=result.candidates)
    result.rig_name, result.coupling_name = rig_cfg.name, coupling_model.name
    return result
