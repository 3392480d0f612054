"""Identify one model family: bind it to the data and run its staged strategy (docs/theory.md#elements).

Every strategy ends in (or consists of) bounded least squares on the torque error
(:func:`~droptower.identify.fit.least_squares_fit`, the engine's one
:func:`~droptower.identify.engine.local.local_fit`); the stages before it are the papers' own
routes to good starting values. Each family's strategy lives beside its parameters in
:mod:`droptower.identify.families` (one module per family).
"""
from __future__ import annotations

import time
from typing import Any

import numpy as np

from droptower.deprecation import renamed_keywords
from droptower.errors import DroptowerError, expects
from droptower.identify.data import Segment, common_units
from droptower.identify.families import STRATEGIES, family_class
from droptower.identify.families.base import COMMON_OPTIONS
from droptower.identify.families.stages import Setup, result_of, setup
from droptower.identify.engine.problem import ServoProblem, one_blas_thread
from droptower.identify.engine.search import SearchPolicy, run_search
from droptower.identify.fit import stage_result
from droptower.identify.noise import servo_noise
from droptower.identify.result import Identification, Parameters, servo_given
from droptower.identify.verdict import servo_verdict
from droptower.io.fields import torsional_fields

#: Values of ``identify(search=...)``.
SEARCH_MODES = ("auto", "always", "never")
#: Families whose identification is one parameter vector for all data (the global search's
#: result replaces the staged one); overlay's parameters come from a map of sine blocks.
SEARCHABLE = ("zerodim6", "zerodim20", "elastoslide", "pfeffer", "masing", "template", "filled_rubber")
#: Candidates of the servo global search per free parameter, at least MIN_CANDIDATES.
CANDIDATES_PER_PARAMETER = 16
MIN_CANDIDATES = 64
#: The servo records' global search (:func:`global_search`), every setting declared: every
#: record in the screening, no prior (servo records pin every direction they fit), no walk of
#: the odd exponent (the staged strategy walks it), no escalation, no basin moves.
SERVO_POLICY = SearchPolicy(starts_per_parameter=CANDIDATES_PER_PARAMETER, min_starts=MIN_CANDIDATES,
                            screen_tests=None, tol=1e-7, prior_weight=None, walk_choices=False, escalation=1,
                            hop_rounds=0, loose_prior_weight=None)
#: Families whose global search is that of a family they contain exactly, followed by their
#: own strategy from its result: the six-parameter model holds the 20-parameter model's
#: structure (its relaxation times, the branch's level and slope), which a search decides; a
#: Latin hypercube over 20 parameters would spend its candidates on table shapes, which the
#: local fit refines from a good six-parameter start anyway (and each of its local fits costs
#: 20 columns per Jacobian).
SEARCH_THROUGH = {"zerodim20": "zerodim6"}


@renamed_keywords(kind="family")
@one_blas_thread
@expects(family="builtins.str", segments=["droptower.identify.data.Segment"])
def identify(family: str, segments: list[Segment], *, init: dict[str, float] | Parameters | None = None,
             bounds: dict[str, tuple[float, float]] | None = None, options: dict[str, Any] | None = None,
             holdout: list[Segment] | None = None, previous: dict[str, Identification] | None = None,
             file: str | None = None, search: str = "auto", seed: int = 0) -> Identification:
    """Identify model family ``family`` from ``segments`` (``kind``, its name in release 0.1, is
    deprecated).

    init, bounds, options: parameter name -> initial value (the strategy starts from it instead
    of its own estimate; the fit refines it), or :class:`~droptower.identify.result.Parameters`
    (a value: the initial value; finite ``min`` / ``max``: the bounds; ``vary=False`` is refused:
    the servo strategies fit every parameter); name -> [lower, upper]; family options (the
    tables of an init TOML file); holdout: data for the hold-out RMSE;
    previous: results of other families on the same data (zerodim20 starts from zerodim6's,
    identified here where not given).
    Translational records (``Segment.units``) may name parameters and options for their units
    (``k1_n_per_m``, ``amplitude_mm``) or the torsional way.
    search: ``"auto"`` runs the global search (:func:`global_search`) when the family's
    staged strategy ends in a poor fit, ``"always"`` after it in any case, ``"never"`` not;
    the better of the two is kept. Every result carries its verdict (:mod:`.verdict`). A fit
    that does not converge is returned with ``converged`` False: the caller decides.
    """
    start = time.perf_counter()
    if not segments:
        raise DroptowerError("no data to identify from")
    units = common_units(segments + list(holdout or []), "fitting and hold-out records")
    init, bounds = servo_given(init, bounds)
    init, bounds, options = (torsional_fields(given or {}, units) for given in (init, bounds, options))
    s = setup(family_class(family), segments, init, bounds, options, file)
    if search not in SEARCH_MODES:
        raise DroptowerError(f"search must be one of {', '.join(SEARCH_MODES)}, got {search!r}")
    inner = SEARCH_THROUGH.get(family)
    start_here = bool(inner) and not (previous or {}).get(inner) and not s.given.all()
    if start_here:
        # the start: the contained family identified as the command line does, its global
        # search included where its staged fit is poor (a poor start would only make the
        # larger model's local fit crawl until its evaluation limit)
        previous = {**(previous or {}), inner: identify(inner, segments, options=_common_options(s.family),
                                                        search=search, seed=seed)}
    result = STRATEGIES[family](s, segments, start, previous=previous)
    noise = servo_noise(segments)
    result.verdict = servo_verdict(result, noise, s.family.parameters, _idle(s.family, result))
    first = (previous or {}).get(inner) if inner else None
    # a start that the contained family's global search gave already: searching through it again repeats it
    searched_start = first is not None and "global_search" in first.extra
    if search == "always" or (search == "auto" and result.verdict.poor and family in SEARCHABLE and not searched_start):
        searched = global_search(s, segments, start, seed, staged=np.array(list(result.parameters.values())))
        searched.verdict = servo_verdict(searched, noise, s.family.parameters, _idle(s.family, searched))
        searched.extra["staged_fit"] = {"nrmse": result.fit_error.nrmse, "verdict": result.verdict.verdict}
        if searched.fit_error.rmse_nm < result.fit_error.rmse_nm:
            result = searched
        else:
            result.extra["global_search"] = searched.extra["global_search"]
    if first is not None:
        result.extra["start"] = {"family": inner, "nrmse": first.fit_error.nrmse, "global_search": searched_start,
                                 **({"staged_fit": first.extra["staged_fit"]} if "staged_fit" in first.extra else {}),
                                 **({"evaluations": first.evaluations} if start_here else {})}
    if holdout:
        result.evaluate_holdout(holdout)
    result.wall_s = time.perf_counter() - start
    return result


def _idle(family: Any, result: Identification) -> list[str]:
    """The parameters of a switched-off part of ``result`` (the family's ``idle_parameters``):
    their bounds are not bound hits."""
    return list(family.idle_parameters(np.array(list(result.parameters.values()), float)))


def global_search(s: Setup, segments: list[Segment], start: float, seed: int = 0,
                  staged: np.ndarray | None = None) -> Identification:
    """The engine's search (:func:`~droptower.identify.engine.search.run_search` with
    :data:`SERVO_POLICY`) on the servo records: Latin-hypercube candidates over the whole
    bounds (every batch in one core call), then the joint least squares from the best three
    distinct ones; for the families of :data:`SEARCH_THROUGH`, :func:`search_through`.
    ``staged``: the staged strategy's result, one more candidate (with its branches' roles
    swapped, another): it competes with the others on cost instead of fixing which branch plays
    which role."""
    fam = s.family
    if fam.kind in SEARCH_THROUGH:
        return search_through(s, segments, start, seed)
    started = time.perf_counter()
    free = ~s.given
    problem = ServoProblem(fam, segments)
    choices = {i: values for i, values in fam.choices().items() if free[i]}  # the elastoslide's odd p
    found = run_search(problem, SERVO_POLICY, s.x0, free, seed=seed, max_nfev=s.max_nfev, choices=choices,
                       starts=None if staged is None else staged[None, :])
    searched = problem.counter.evaluations
    final = stage_result(problem, found.fit, "global search: joint", started)
    final.evaluations -= searched
    return result_of(s, segments, found.fit.values.copy(), [final], start,
                     extra={"global_search": found.summary, "search_evaluations": searched})


def search_through(s: Setup, segments: list[Segment], start: float, seed: int = 0) -> Identification:
    """The global search of a family that contains another exactly (:data:`SEARCH_THROUGH`):
    the contained family's global search, then the family's own strategy from that result
    (the user's initial values, bounds and options kept)."""
    fam = s.family
    inner = global_search(setup(family_class(SEARCH_THROUGH[fam.kind]), segments, options=_common_options(fam)),
                          segments, start, seed)
    init = {n: v for n, v, given in zip(fam.names, s.x0, s.given) if given}
    bounds = {p.name: (p.lower, p.upper) for p, user in zip(fam.parameters, s.bounded) if user}
    fresh = setup(type(fam), segments, init, bounds, fam.options)  # the strategy narrows bounds around its start
    result = STRATEGIES[fam.kind](fresh, segments, start, previous={inner.family: inner})
    result.extra["global_search"] = {**inner.extra["global_search"], "through": inner.family}
    result.extra["search_evaluations"] = inner.evaluations
    return result


def _common_options(family) -> dict[str, Any]:
    """The options of ``family`` every family takes (for the family it contains)."""
    return {k: v for k, v in family.options.items() if k in COMMON_OPTIONS}
