"""A coupling model fitted to drop-test decays (:func:`identify_drops`; the ``identify`` command wraps it for drop tests).

Every test is re-simulated from its impact (:class:`~droptower.identify.engine.problem.DropProblem`,
:mod:`.lever`): the lever (inertia J) starts at rest position with the rate the impact gave it
(:mod:`.droplogs`) and decays freely on the candidate coupling, which starts in the state the
rig's conditioning leaves it in (Rapp et al.'s (2022) pre-straining; ``conditioning=False``:
virgin). The residual is the angle over the compared window (and the torque where the log has
it, weighted by ``torque_weight``), each test's part divided by its peak and by the square root
of its sample count, so that small drops count as much as large ones. All tests of all
parameter sets of a call (a candidate, or the columns of a forward-difference Jacobian) decay
in ONE batched call of the core.

The fit is the engine's search (:func:`~droptower.identify.engine.search.run_search` with
:data:`DROP_POLICY`): Latin-hypercube candidates over the whole bounds and around the first
guess on at most :data:`SEARCH_TESTS` tests spread over the campaign (they only decide the
basin), bounded trust-region-reflective least squares from the best three distinct candidates
(and the winner with its branches' roles swapped), each with a weak prior toward its start
that pins only the directions the data do not determine (reported as non-identifiable
combinations), the lowest cost refined on all fitting tests; the family's moves into
neighbouring basins, a wider search and a looser prior where the verdict is poor. The verdict
(:func:`~droptower.identify.verdict.drop_verdict`) compares the angle error with the logs'
pre-trigger noise, the re-simulation's accuracy and the fitted model's integration error at the
logs' step (docs/theory.md#verdict). Standard errors: the larger of s^2 (J'J)^-1 inflated for
the residual's lag-1 correlation and the cluster-robust (sandwich) covariance with the tests as
clusters (a test's systematic misfit counts once, not once per sample), plus, in quadrature,
the parameters' shift when the decays are integrated on half the step (the integration step's
bias, Richardson-scaled for a first-order error), so they do not claim more than the
simulation's accuracy supports. A fraction of the tests (spread over inertias and amplitudes)
is held out and predicted.
"""
from __future__ import annotations

import dataclasses
import functools
import math
import time
from typing import Any, Callable

import numpy as np

from droptower.deprecation import moved_names, renamed_keywords
from droptower.errors import DroptowerError
from droptower.fit_defaults import HOLDOUT_FRACTION
from droptower.identify.data import DataScale
from droptower.identify.droplogs import DropDecay, first_cycle_readings
from droptower.identify.engine.problem import (PRIOR_WEIGHT, DropFitSettings, DropProblem, clip_to_bounds,
                                               one_blas_thread)
from droptower.identify.engine.search import SearchPolicy, SearchResult, run_search
from droptower.identify.families import family_class
from droptower.identify.families.base import Family
from droptower.identify.families.stages import setup_family
from droptower.identify.result import (DROPS, Identification, Parameters, fitted_parameters, lag1_correlation,
                                       place_guesses, split_given)
from droptower.identify.verdict import RESIMULATION_ACCURACY, bound_hits, drop_verdict
from droptower.rates import SERVO_SAMPLE_RATE_HZ
from droptower.rheology import Coupling

__all__ = ["DROP_FAMILIES", "DROP_POLICY", "DropFitSettings", "DropProblem", "FIT_OPTIONS", "HOLDOUT_FRACTION",
           "READ_OPTIONS", "RESIMULATION_ACCURACY", "SERVO_GRID", "drop_scale", "drop_verdict", "holdout_split",
           "identify_drops", "per_test_errors", "servo_agreement", "servo_grid", "split_options", "summarise",
           "tested_grid", "tested_range"]

#: The families a drop-test campaign can identify (the servo-only families need steady sine blocks).
DROP_FAMILIES = ("elastoslide", "zerodim6", "masing", "template", "pfeffer", "filled_rubber")
#: the release-0.1 name of :data:`DROP_FAMILIES`, answered with a DeprecationWarning (module ``__getattr__``)
_renamed = moved_names(__name__, {"DROP_KINDS": "DROP_FAMILIES"}, globals())
#: Relative tolerance of the fit (cost, step): far below the sensors' noise on the angle.
TOL = 1e-6
#: Weight of the prior of the last refinement of a fit still poor after the escalated search.
LOOSE_PRIOR_WEIGHT = 1e-6
#: Candidates of the global search per free parameter (Latin hypercube over the bounds), at least MIN_STARTS.
STARTS_PER_PARAMETER = 24
MIN_STARTS = 96
#: Local least-squares fits from the best distinct candidates.
LOCAL_FITS = 3
#: A fit whose verdict is poor searches again with this many times the candidates (and two
#: more local fits).
ESCALATION = 3
#: A fit of the family's own coupling that ended in a basin beside its optimum leaves a few
#: times the noise allowance (measured 2-9 x on masing's broad yield spreads, the truth 0.2-0.3 x):
#: the family's moves into other basins (its ``basin_moves``) run while the error over the
#: allowance lies in this range; above it (tens of times) the family misses structure in
#: the data, which no move into a neighbouring basin mends. From the verdict's limit
#: (:data:`~droptower.identify.verdict.NOISE_RATIO`): the moves cannot change a good verdict,
#: and on a good fit they took a third of masing's slowest fits' time.
HOP_RANGE = (2.0, 20.0)
#: Rounds of moves at most (each from the previous round's better fit; they stop when a round finds
#: nothing better or the fit leaves HOP_RANGE). Raced rounds cost a third to a half of full ones, so
#: four fit in the time two took: masing's hard draw #38 went 5.7 -> 4.0 -> 3.65 -> 3.67 -> 0.8 x its
#: allowance (the truth 0.22 x), a false alarm after two rounds.
HOP_ROUNDS = 4
#: A further round of moves only where the last lowered the cost by this fraction: masing's hard draws
#: #22, #31 and #41 took rounds that lowered it by 0.02-0.5 %, 4-13 s of rounds that changed nothing
#: (the escalated search found their fits); rounds on the way to a good fit lowered it by 1.4-44 %
#: (#38: 44, 12, 1.5 %, then 14 % to 0.8 x the allowance; its third round RAISED the error over the
#: allowance 3.65 -> 3.67 x, the torque's part of the cost falling: the cost, not that ratio, measures
#: a round's gain).
HOP_GAIN = 0.01
#: Evaluations of each move's local fit before the race's cuts (:meth:`~droptower.identify.engine.search._Search.race`).
RACE_NFEV = 3
#: The moves' local fits that run on to convergence after the race. Two, not one: bench_false_alarms'
#: masing draw #53 ended at 2.13 x its allowance with one (its fourth round's best basin ranked second
#: after six evaluations), 0.98 x with two; masing over 100 draws 3 % -> 2 % false alarms, p90 23.1 ->
#: 19.8 s CPU (benchmarks/results/false_alarms.txt).
RACE_FINALISTS = 2
#: Tests the global search's candidates are evaluated on (spread over inertias and amplitudes):
#: a large campaign adds no new information to the search, only cost.
SEARCH_TESTS = 12


#: The drop-test fit's search, every setting declared (:class:`~droptower.identify.engine.search.SearchPolicy`).
DROP_POLICY = SearchPolicy(starts_per_parameter=STARTS_PER_PARAMETER, min_starts=MIN_STARTS, local_fits=LOCAL_FITS,
                           screen_tests=SEARCH_TESTS, tol=TOL, prior_weight=PRIOR_WEIGHT, escalation=ESCALATION,
                           hop_range=HOP_RANGE, hop_rounds=HOP_ROUNDS, hop_gain=HOP_GAIN,
                           race_nfev=RACE_NFEV, race_finalists=RACE_FINALISTS,
                           loose_prior_weight=LOOSE_PRIOR_WEIGHT)

#: The fit's settings where none are given (frozen: one instance serves every call).
DEFAULT_SETTINGS = DropFitSettings()

#: Options of the fit among a family's options: each sets the :class:`DropFitSettings` field of
#: its name (``conditioning``: False for a virgin coupling).
FIT_OPTIONS = ("substeps", "torque_weight", "max_nfev", "seed", "conditioning")
#: Options of reading the logs (:func:`~droptower.identify.drop_campaign.read_drop_tests`): refused by a
#: fit of decays already read, which could not honour them.
READ_OPTIONS = ("cycles", "initial_rate", "skip_s")


def split_options(settings: DropFitSettings, options: dict[str, Any] | None
                  ) -> tuple[DropFitSettings, dict[str, Any]]:
    """(``settings`` with the fit's options among ``options`` applied, the family's options left).

    An option of the fit that ``settings`` already sets to another value than its default is
    refused (given twice), as is an option of reading the logs (the decays are read already).
    The family refuses what is left and it does not know.
    """
    options = dict(options or {})
    read = sorted(k for k in options if k in READ_OPTIONS)
    if read:
        raise DroptowerError(f"option(s) {', '.join(read)} apply to reading the logs (read_drop_tests), "
                             "not to fitting decays already read")
    default, changes = DropFitSettings(), {}
    for key in [k for k in options if k in FIT_OPTIONS]:
        value = options.pop(key)
        if key == "conditioning":
            value = settings.conditioning if value else None
            if value is None and settings.conditioning is None:
                continue
        else:
            value = type(getattr(default, key))(value)
            if isinstance(value, int) and value < (1 if key == "substeps" else 0):
                raise DroptowerError(f"option {key} must be a{' positive' if key == 'substeps' else ' non-negative'} "
                                     f"integer, got {value}")
        here = getattr(settings, key)
        if key != "conditioning" and here != getattr(default, key) and here != value:
            raise DroptowerError(f"option {key} = {value!r} contradicts the settings' {key} = {here!r}")
        changes[key] = value
    return dataclasses.replace(settings, **changes), options


def drop_scale(decays: list[DropDecay]) -> DataScale:
    """Typical magnitudes of a drop campaign, for the families' bounds and first guesses: the
    linear stiffness J omega^2 of the first cycles, their amplitudes, rates and frequencies."""
    k = np.array([d.inertia_kgm2 * (2 * np.pi * d.frequency_hz) ** 2 for d in decays])
    amp = max(d.amplitude_rad for d in decays)
    return DataScale(amp, amp, float(np.median(k)) * amp, float(np.median(k)),
                     max(abs(d.rate0_rad_per_s) for d in decays), float(np.median([d.frequency_hz for d in decays])))


def per_test_errors(problem: DropProblem, values: np.ndarray) -> list[dict[str, Any]]:
    """Per test: RMS angle (and torque) error over the compared window as a fraction of the
    test's peak (``angle_nrmse``, ``torque_nrmse``)."""
    a, q = problem.simulate(values[None])
    out = []
    for i, d in enumerate(problem.decays):
        n = d.time_s.size
        row = {"file": d.name, "inertia_kgm2": d.inertia_kgm2, "amplitude_deg": math.degrees(d.amplitude_rad),
               "frequency_hz": d.frequency_hz, "rate0_rad_per_s": d.rate0_rad_per_s, "rate_source": d.rate_source,
               "angle_nrmse": float(np.sqrt(np.mean((a[0, i, :n] - d.angle_rad) ** 2)) / d.amplitude_rad)}
        if d.torque_nm is not None:
            row["torque_nrmse"] = float(np.sqrt(np.mean((q[0, i, :n] - d.torque_nm) ** 2)) / d.torque_amplitude_nm)
        out.append(row)
    return out


def summarise(per_test: list[dict[str, Any]]) -> dict[str, Any]:
    """RMS over tests of the per-test errors, and the list."""
    out: dict[str, Any] = {"tests": len(per_test)}
    for key in ("angle_nrmse", "torque_nrmse"):
        vals = [r[key] for r in per_test if key in r]
        if vals:
            out[key] = float(np.sqrt(np.mean(np.square(vals))))
            out[f"{key}_max"] = float(np.max(vals))
    out["per_test"] = per_test
    return out


def holdout_split(decays: list[DropDecay], fraction: float) -> tuple[list[int], list[int]]:
    """(fitting, hold-out) test indices: every k-th test in the order of inertia and amplitude,
    so the hold-out tests span the campaign; none below 5 tests."""
    n = len(decays)
    n_hold = int(math.floor(fraction * n)) if n >= 5 else 0
    order = sorted(range(n), key=lambda i: (decays[i].inertia_kgm2, decays[i].amplitude_rad))
    hold = sorted(order[int(j)] for j in np.round(np.linspace(1, n - 2, n_hold)).astype(int)) if n_hold else []
    return [i for i in range(n) if i not in hold], hold


@renamed_keywords(kind="family")
@one_blas_thread
def identify_drops(family: str, decays: list[DropDecay], *, excluded: list[dict[str, str]] | None = None,
                   settings: DropFitSettings = DEFAULT_SETTINGS, init: dict[str, float] | Parameters | None = None,
                   bounds: dict[str, tuple[float, float]] | None = None,
                   options: dict[str, Any] | None = None) -> Identification:
    """Fit family ``family`` (:data:`DROP_FAMILIES`) to the free decays ``decays``.

    Parameters
    ----------
    family : str
        The model family's name (``kind`` in release 0.1: deprecated).
    decays : list of DropDecay
        The drop tests' free decays (:func:`~droptower.identify.droplogs.read_decays`).
    excluded : list of dict, optional
        The tests left out when reading (reported with the result).
    settings : DropFitSettings
        How the decays are re-simulated and fitted.
    init : dict or Parameters, optional
        Parameter name -> value held fixed, or :class:`~droptower.identify.result.Parameters`
        (``vary=False``: held; finite ``min`` / ``max``: bounds; a varying one's value: the
        first guess).
    bounds : dict, optional
        Parameter name -> (lower, upper).
    options : dict, optional
        The family's options, as for :func:`~droptower.identify.identify` (e.g. ``template``),
        and the fit's (:data:`FIT_OPTIONS`: each sets the field of ``settings`` of its name).
        Unknown options are refused by name, as are the reading's (:data:`READ_OPTIONS`).

    Returns
    -------
    Identification
        With ``data`` :data:`~droptower.identify.result.DROPS`: ``fit_error`` / ``holdout_error`` the angle
        errors (fractions of each test's amplitude) over the fitting / held-out tests.
    """
    start = time.perf_counter()
    kind = family  # the name; ``family`` below is the family bound to the data's scale
    init, bounds, guesses = split_given(init, bounds)
    if kind not in DROP_FAMILIES:
        raise DroptowerError(f"family {kind!r} cannot be identified from drop tests (families: {', '.join(DROP_FAMILIES)})")
    if len(decays) < 2:
        raise DroptowerError(f"{len(decays)} usable drop test(s): at least 2 are needed"
                             + (f" ({len(excluded)} excluded)" if excluded else ""))
    settings, options = split_options(settings, options)
    family = family_class(kind)(drop_scale(decays), options)
    fit_idx, hold_idx = holdout_split(decays, settings.holdout_fraction)
    problem = DropProblem(family, [decays[i] for i in fit_idx], settings)
    x0, first, free, deferred, given = drop_starts(family, problem.decays, init, bounds, guesses)
    choose_p = "p" in family.names and not given[family.names.index("p")]
    found = run_search(problem, DROP_POLICY, x0, free, seed=settings.seed, max_nfev=settings.max_nfev, first=first,
                   deferred=deferred, choices=family.choices() if choose_p else {})
    hold = DropProblem(found.problem.family, [decays[i] for i in hold_idx], settings) if hold_idx else None
    result = drop_result(found, family.parameters, ~given, hold)
    result.tests_used = [decays[i].name for i in fit_idx]
    result.tests_excluded = list(excluded or [])
    result.wall_s = time.perf_counter() - start
    return result


def drop_starts(family: Family, decays: list[DropDecay], init: dict[str, float] | None,
                bounds: dict[str, tuple[float, float]] | None, guesses: dict[str, float]
                ) -> tuple[np.ndarray | Callable[[], np.ndarray], np.ndarray | None, np.ndarray, np.ndarray,
                           np.ndarray]:
    """The search's starts on the fitting tests ``decays``: (the first guess, or for a family
    with a deferred part the function that makes it; the first search's guess without that part
    (None without one); the free parameters; the deferred ones; the given ones). The family's
    closed form reads its guess off the first cycles (``guess_from_readings``), the user's
    guesses override it; the elastoslide's odd p is chosen by the search, never fitted."""
    s = setup_family(family, init, bounds)
    params, x0, given = family.parameters, s.x0, s.given
    free = np.array([p.name != "p" for p in params]) & ~given
    if not free.any():
        raise DroptowerError(f"every parameter of family {family.kind} has a given initial value: nothing to fit")
    # a family's deferred parameters (a part it switches off first): held off in the first
    # search, freed in the wider one after a poor verdict
    deferred = np.isin(family.names, family.DEFERRED) & free
    readings = first_cycle_readings(decays)

    def guess(fam: Family, x: np.ndarray, held: np.ndarray) -> np.ndarray:
        """The closed form's first guess from ``x`` (``held`` kept), the user's guesses over it."""
        x = np.array(fam.guess_from_readings(*readings, x, held), float)
        if guesses:
            place_guesses(family.kind, fam.names, x, guesses)
            x = np.where(held, x, clip_to_bounds(fam.parameters, x))
        return x

    if not deferred.any():
        x0 = guess(family, x0, given)
        return x0, None, free, deferred, given
    # the first search's guess from the closed form without the deferred part; the whole
    # family's only where that search ends poor (the escalated search starts there): the
    # closed form's fit costs seconds per call on a large campaign (its readings, one per test)
    x_off = guess(family.without_branch(), family.branch_off(x0), given | deferred)
    return functools.partial(guess, family, x0.copy(), given.copy()), x_off, free, deferred, given


def drop_result(found: SearchResult, parameters: list, varied: np.ndarray, hold: DropProblem | None
                ) -> Identification:
    """The :class:`Identification` of a search's fit on drop tests: the standard errors (the
    larger of the lag-1 inflated and the tests-clustered covariance, the integration step's
    bias added), the per-test errors on the fitting and the held-out tests (``hold``), the
    verdict; ``parameters``: the family's as the user bounded them; ``varied``: not given."""
    sol, problem, half = found.fit, found.problem, found.half_step
    family = problem.family
    # the integration step's bias: the parameters' shift to the half step, Richardson-scaled
    # for the first-order part of the error (the core's rate-dependent elements, see .lever)
    bias_z = sol.step_bias_z(problem.weighted(*half)[0])
    std = sol.std_error(lag1_correlation([sol.residual]), extra_z=bias_z, groups=problem.groups)
    fit_err = summarise(per_test_errors(problem, sol.values))
    verdict, rss, n_samples = problem.verdict(sol.values, bound_hits(parameters, sol.at_bounds), sol.converged,
                                              half_step=half)
    return Identification(
        family.kind, fitted_parameters(parameters, sol.values, std, varied), list(sol.at_bounds), fit_err,
        family.coupling(sol.values), data=DROPS, holdout_error=summarise(per_test_errors(hold, sol.values)) if hold else None,
        derived=family.derived(sol.values), verdict=verdict, family_model=family, message=sol.message,
        non_identifiable=sol.non_identifiable, tests_held_out=[d.name for d in hold.decays] if hold else [],
        search=found.summary, angle_rss_rad2=rss, angle_samples=n_samples, converged=bool(sol.converged),
        evaluations=problem.counter.evaluations, nfev=sol.nfev)


def tested_range(decays: list[DropDecay]) -> tuple[tuple[float, float], tuple[float, float]]:
    """The campaign's first-cycle amplitudes (rad) and frequencies (Hz), (min, max) each: where
    the identified model is backed by data."""
    a = [d.amplitude_rad for d in decays]
    f = [d.frequency_hz for d in decays]
    return (min(a), max(a)), (min(f), max(f))


#: The servo grid inside the tested range, (amplitudes, frequencies), each geometric: the grid of
#: the identification's acceptance measure (:func:`servo_agreement`, docs/guide/identification.md)
#: and of the drop-test report's servo prediction
SERVO_GRID = (4, 3)


def tested_grid(decays: list[DropDecay], n_amplitudes: int = SERVO_GRID[0],
                n_frequencies: int = SERVO_GRID[1]) -> tuple[np.ndarray, np.ndarray]:
    """The servo grid inside the campaign's tested range (:func:`tested_range`): ``n_amplitudes``
    amplitudes (rad) and ``n_frequencies`` frequencies (Hz), geometrically spaced, ends included."""
    (a0, a1), (f0, f1) = tested_range(decays)
    return np.geomspace(a0, a1, n_amplitudes), np.geomspace(f0, f1, n_frequencies)


def servo_grid(coupling: Coupling, amplitudes_rad: np.ndarray, frequencies_hz: np.ndarray) -> Any:
    """The virtual servo bench's K' and loss factor of ``coupling`` on a grid (DataFrame), sampled
    at least 40 times per cycle."""
    from droptower.servo import run_grid

    rate = max(SERVO_SAMPLE_RATE_HZ, 40.0 * float(np.max(frequencies_hz)))
    return run_grid(coupling, amplitudes_rad, frequencies_hz, sample_rate_hz=rate)


def servo_agreement(fitted: Coupling, truth: Coupling, decays: list[DropDecay], n_amplitudes: int = SERVO_GRID[0],
                    n_frequencies: int = SERVO_GRID[1]) -> dict[str, float]:
    """RMS relative deviation of the fitted coupling's storage stiffness and loss factor from
    ``truth``'s on the servo grid inside the tested range (:func:`tested_grid`; the acceptance measure)."""
    amps, freqs = tested_grid(decays, n_amplitudes, n_frequencies)
    fit, ref = servo_grid(fitted, amps, freqs), servo_grid(truth, amps, freqs)
    dk = fit["storage_stiffness_nm_per_rad"].to_numpy() / ref["storage_stiffness_nm_per_rad"].to_numpy() - 1.0
    de = fit["loss_factor"].to_numpy() / ref["loss_factor"].to_numpy() - 1.0
    return {"storage_stiffness_rms": float(np.sqrt(np.mean(dk ** 2))), "storage_stiffness_max": float(np.max(np.abs(dk))),
            "loss_factor_rms": float(np.sqrt(np.mean(de ** 2))), "loss_factor_max": float(np.max(np.abs(de)))}


def __getattr__(name: str) -> object:
    """Deprecated names of the drop-test search, which the engine's
    :func:`~droptower.identify.engine.search.run_search` now runs whole (removed in the next release):
    ``drop_hops`` (the search's basin moves from a fit); ``DROP_KINDS`` is :data:`DROP_FAMILIES`."""
    import warnings

    if name == "DROP_KINDS":
        return _renamed(name)
    if name == "drop_hops":
        warnings.warn("droptower.identify.dropfit.drop_hops is deprecated: the engine's search runs the family's "
                      "basin_moves", DeprecationWarning, stacklevel=2)
        return _drop_hops
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def _drop_hops(problem: DropProblem, family: Family, incumbent: np.ndarray, free: np.ndarray,
               settings: DropFitSettings) -> tuple[Any, dict[str, Any]]:
    from droptower.identify.engine.search import _Search

    return _Search(DROP_POLICY, settings.seed, settings.max_nfev, {}).hops(problem.with_family(family), incumbent,
                                                                          free)
