"""Identify one model family: bind it to the data and run its staged strategy (NOTES §2).

Every strategy ends in (or consists of) bounded least squares on the torque error
(:func:`~droptower.identify.fit.least_squares_fit`); the stages before it are the papers' own
routes to good starting values. Each family's strategy lives beside its parameters in
:mod:`droptower.identify.families` (one module per family).
"""
from __future__ import annotations

import time
from typing import Any

from droptower.errors import DroptowerError
from droptower.identify.data import Segment, common_units
from droptower.identify.families import STRATEGIES, family_class
from droptower.identify.families.stages import setup
from droptower.identify.fit import Identification
from droptower.io.fields import torsional_fields


def identify(kind: str, segments: list[Segment], *, init: dict[str, float] | None = None,
             bounds: dict[str, tuple[float, float]] | None = None, options: dict[str, Any] | None = None,
             holdout: list[Segment] | None = None, previous: dict[str, Identification] | None = None,
             file: str | None = None) -> Identification:
    """Identify model family ``kind`` from ``segments``.

    init, bounds, options: from ``--params INIT.toml`` (parameter name -> initial value;
    name -> [lower, upper]; family options); holdout: data for the hold-out RMSE;
    previous: results of other families on the same data (zerodim20 starts from zerodim6's).
    Translational records (``Segment.units``) may name parameters and options for their units
    (``k1_n_per_m``, ``amplitude_mm``) or the torsional way. A fit that does not converge is
    returned with ``converged`` False: the caller decides.
    """
    start = time.perf_counter()
    if not segments:
        raise DroptowerError("no data to identify from")
    units = common_units(segments + list(holdout or []), "fitting and hold-out records")
    init, bounds, options = (torsional_fields(given or {}, units) for given in (init, bounds, options))
    s = setup(family_class(kind), segments, init, bounds, options, file)
    result = STRATEGIES[kind](s, segments, start, previous=previous)
    if holdout:
        result.evaluate_holdout(holdout)
    result.time_s = time.perf_counter() - start
    return result
