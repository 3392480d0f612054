"""The engine's problem layer: parameter sets -> residual vectors, in one batched call.

A :class:`Problem` is what a least-squares fit and a global search need of the data and the
model, as lmfit's ``Minimizer`` needs an objective: its :attr:`~Problem.parameters`
(:class:`FitVariable`: name with unit, bounds, optimised variable), :meth:`~Problem.residuals`
of many parameter sets at once (rows (M, n) -> (M, R), so that every candidate of a batch
and every column of a forward-difference Jacobian go to the rheological core in ONE call),
the cluster of each residual (:attr:`~Problem.groups`: a segment, a drop test), and the one
count of evaluations (:attr:`~Problem.counter`). A row the core refuses (a falling table, a
coupling the parser rejects) is not an error: its residuals are NaN (:meth:`Problem.couplings`,
the one fallback), which costs inf where costs are compared (:func:`row_costs`) and
:data:`REFUSED_RESIDUAL` for the optimiser (:func:`finite_residuals`).

Two problems of the package: :class:`ServoProblem` (servo records: the torque under imposed
angle histories, :func:`~droptower.identify.result.servo_residual`) and :class:`DropProblem`
(drop tests: each test's free decay re-simulated from its impact, docs/theory.md#decay);
:class:`FunctionProblem` wraps any batched residual function. :meth:`Problem.with_prior` adds
a weak prior toward a start, :meth:`Problem.screening` the few tests a search screens on.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable, Protocol

import numpy as np
from threadpoolctl import threadpool_limits

from droptower.errors import DroptowerError
from droptower.fit_defaults import HOLDOUT_FRACTION
from droptower.identify.budget import check as check_budget
from droptower.identify.lever import at_times, free_decay
from droptower.identify.result import servo_residual
from droptower.rheology import Coupling, CouplingState
from droptower.rig.config import PRELOAD_HOLD_S, PRELOAD_RAMP_S
from droptower.rig.preload import hold_at
from droptower.identify.verdict import NOISE_RATIO, drop_verdict

#: The linear algebra of a fit on ONE thread (a decorator). The cores belong to the core's
#: batched simulations; a fit's matrices are tall and narrow (residuals x parameters, e.g.
#: 50 000 x 20), which threads hardly speed up, while a BLAS thread pool whose threads wait for
#: a busy core stalls every call: the SVD that each trust-region step takes of such a Jacobian
#: took 0.03 s on one thread and 0.4 s on two with both cores busy (measured on the
#: project's 2-core machine), more than the simulations of the step.
one_blas_thread = threadpool_limits.wrap(limits=1, user_api="blas")

#: Histories up to this factor longer than the shortest of a call share it (padding waste).
PAD_FACTOR = 1.5
#: The residual a least-squares optimiser sees for a sample the core refused or that diverged
#: (non-finite): a failed simulation is a terrible candidate, never a good one, and the optimiser
#: needs finite numbers. Where costs are compared (:func:`row_costs`) such a row costs inf.
REFUSED_RESIDUAL = 1e30
#: Weight of the prior toward the starting point, per square root of the number of clusters
#: (tests) of the problem (:meth:`Problem.with_prior`).
PRIOR_WEIGHT = 1e-3


@dataclass(frozen=True)
class FitVariable:
    """One variable of the optimiser: a model parameter's name (with its unit as suffix), its
    bounds, and how it is optimised. (The result's parameters, with values and standard
    errors, are :class:`droptower.identify.result.Parameter`.)

    log: optimised as ln(value) (positive parameters spanning decades; lower > 0); otherwise
    as value / scale (parameters that may be 0).
    """

    name: str
    lower: float
    upper: float
    log: bool = True
    scale: float = 1.0

    def to_z(self, value: float) -> float:
        """The optimised variable of ``value`` (ln value, or value / scale)."""
        return float(np.log(value)) if self.log else value / self.scale

    def to_value(self, z: float) -> float:
        """The parameter's value (its unit) of the optimised variable ``z``."""
        return float(np.exp(z)) if self.log else z * self.scale

    def dvalue_dz(self, value: float) -> float:
        """d value / d z at ``value`` (the parameter's unit per unit of z)."""
        return value if self.log else self.scale

    def z_bounds(self) -> tuple[float, float]:
        """The bounds in the optimised variable."""
        return self.to_z(self.lower), self.to_z(self.upper)


class Variables:
    """The optimised variables of the parameters ``idx`` of ``parameters``, many at once: what
    :meth:`FitVariable.to_z` and :meth:`FitVariable.to_value` give one by one, to the last bit
    (the same operations, each element by itself: ``exp``/``log`` of the logarithmic ones, the
    product or quotient by the scale of the others), without a Python call per number (a
    Jacobian of n columns takes n^2 of them)."""

    def __init__(self, parameters: list[FitVariable], idx: np.ndarray):
        self.idx = np.asarray(idx, dtype=np.int64)
        self.log = np.array([parameters[i].log for i in self.idx], dtype=bool)
        self.lin = ~self.log
        self.scale = np.array([parameters[i].scale for i in self.idx], dtype=float)[self.lin]

    def values(self, z: np.ndarray) -> np.ndarray:
        """The parameters' values (their units) of the optimised variables ``z`` (..., k)."""
        z = np.asarray(z, dtype=float)
        out = np.empty(z.shape)
        out[..., self.log] = np.exp(z[..., self.log])
        out[..., self.lin] = z[..., self.lin] * self.scale
        return out

    def z(self, values: np.ndarray) -> np.ndarray:
        """The optimised variables (..., k) of the parameters ``idx`` of ``values`` (..., n)."""
        v = np.asarray(values, dtype=float)[..., self.idx]
        out = np.empty(v.shape)
        out[..., self.log] = np.log(v[..., self.log])
        out[..., self.lin] = v[..., self.lin] / self.scale
        return out


@dataclass
class Counter:
    """Model evaluations: parameter sets simulated over their data, and calls of the core."""

    evaluations: int = 0
    core_calls: int = 0


class Model(Protocol):
    """What the engine needs of a model family."""

    parameters: list[FitVariable]
    #: Integration steps per data sample.
    substeps: int

    def batch(self, values: np.ndarray) -> Coupling:
        """One coupling whose parameter sets are the rows of ``values`` (M, n)."""

    def move_choice(self, v: np.ndarray, index: int, value: float, rate_rad_per_s: float) -> np.ndarray:
        """``v`` with a parameter of a few values moved to ``value``."""

    def coupling(self, v: np.ndarray) -> Coupling:
        """The coupling of one parameter vector."""


def check_in_bounds(parameters: list[FitVariable], values: np.ndarray, file: str | None = None) -> None:
    """A one-line error for the first value outside its parameter's bounds."""
    for p, v in zip(parameters, values):
        if not (np.isfinite(v) and p.lower <= v <= p.upper):
            raise DroptowerError(f"initial value {p.name} = {v:g} is outside its bounds [{p.lower:g}, {p.upper:g}]",
                                 file=file)


def clip_to_bounds(parameters: list[FitVariable], values: np.ndarray) -> np.ndarray:
    """Data-driven guesses pulled strictly inside the bounds (TRF starts from an interior point)."""
    out = np.array(values, dtype=float)
    for i, p in enumerate(parameters):
        lo, hi = p.z_bounds()
        margin = 1e-6 * (hi - lo)
        z = p.to_z(min(max(out[i], p.lower), p.upper))
        out[i] = p.to_value(float(np.clip(z, lo + margin, hi - margin)))
    return out


def at_bounds(parameters: list[FitVariable], values: np.ndarray, rel: float = 1e-6) -> list[str]:
    """Names of the parameters whose value lies on (within ``rel`` of the range from) a bound."""
    out = []
    for p, v in zip(parameters, values):
        lo, hi = p.z_bounds()
        z = p.to_z(min(max(float(v), p.lower), p.upper))
        if min(z - lo, hi - z) <= rel * (hi - lo):
            out.append(p.name)
    return out


def finite_residuals(r: np.ndarray) -> np.ndarray:
    """``r`` with every non-finite sample, and every sample beyond :data:`REFUSED_RESIDUAL` (a
    simulation that diverged without overflowing), replaced by :data:`REFUSED_RESIDUAL`: the
    squares of 1e300 overflow inside the trust-region solver."""
    with np.errstate(invalid="ignore"):
        return np.where(np.isfinite(r) & (np.abs(r) < REFUSED_RESIDUAL), r, REFUSED_RESIDUAL)


def row_costs(r: np.ndarray) -> np.ndarray:
    """Sum of squared residuals of each row of ``r`` (M, R); inf for a row with any non-finite
    sample (the one policy for rows the core refuses: :data:`REFUSED_RESIDUAL`)."""
    r = np.atleast_2d(r)
    with np.errstate(all="ignore"):
        return np.where(np.isfinite(r).all(axis=1), np.sum(np.where(np.isfinite(r), r, 0.0) ** 2, axis=1), np.inf)


def admissible_couplings(model: Model, rows: np.ndarray) -> tuple[Coupling | None, np.ndarray]:
    """One coupling over the parameter sets ``rows`` (M, n), and which rows the core accepts:
    a refused row (e.g. a falling table) gets the first admissible row's set, and its results
    are to be NaN (None when no row is admissible). The one fallback for refused rows."""
    try:
        return model.batch(rows), np.ones(len(rows), bool)
    except DroptowerError:
        pass
    good, sets = np.zeros(len(rows), bool), []
    for i, v in enumerate(rows):
        try:
            sets.append(model.coupling(v))
            good[i] = True
        except DroptowerError:
            sets.append(None)
    if not good.any():
        return None, good
    first = next(c for c in sets if c is not None)
    return Coupling.stack([c if c is not None else first for c in sets]), good


# ---------------------------------------------------------------------------- the base
class Problem:
    """Parameter sets -> residual vectors of one identification, in one batched call.

    Subclasses set :attr:`parameters` (the optimiser's variables), :attr:`counter` (the one
    count of evaluations, shared by the problems made from this one) and implement
    :meth:`evaluate`; :attr:`groups` (the cluster of each residual) defaults to one cluster
    per residual.
    """

    parameters: list[FitVariable]
    counter: Counter

    # -------------------------------------------------------------- per problem
    def evaluate(self, rows: np.ndarray, substeps: int | None = None) -> np.ndarray:  # pragma: no cover - abstract
        """(M, R) residual vectors of the parameter sets ``rows`` (M, n); NaN rows for parameter
        sets the core refuses; ``substeps``: integration steps per sample (None: the problem's)."""
        raise NotImplementedError

    @property
    def n_clusters(self) -> int:
        """Independent parts of the data (tests, segments): the prior's weight grows with their
        square root."""
        return 1

    @property
    def groups(self) -> np.ndarray | None:
        """The cluster of each residual (for cluster-robust standard errors); None: independent."""
        return None

    @property
    def substeps(self) -> int:
        """Integration steps per data sample."""
        return 1

    @property
    def typical_rate_rad_per_s(self) -> float:
        """The data's typical angular rate (rad/s), where a family moves a rate parameter with a
        discrete one (:meth:`~droptower.identify.families.base.Family.move_choice`)."""
        return 1.0

    def screening(self, n_clusters: int | None) -> "Problem":
        """The problem a search screens its candidates on: at most ``n_clusters`` of its
        clusters (itself: every cluster, the default)."""
        return self

    def without_deferred(self) -> "Problem":
        """The problem of the family without the part it defers (itself by default)."""
        return self

    def basin_moves(self, values: np.ndarray | None, free: np.ndarray) -> np.ndarray:
        """Parameter sets in the basins beside the fit ``values`` (none by default)."""
        return np.empty((0, len(self.parameters)))

    def move_choice(self, values: np.ndarray, index: int, value: float) -> np.ndarray:
        """``values`` with parameter ``index`` (one of a few values) set to ``value``."""
        out = np.array(values, float)
        out[index] = value
        return out

    def half_step(self, values: np.ndarray) -> Any:
        """The fit ``values`` re-simulated on half the integration step (what the problem's
        :meth:`error_over_allowance` needs; None: the problem does not judge fits)."""
        return None

    def error_over_allowance(self, values: np.ndarray, half_step: Any = None) -> float:
        """The fit's error over what the data allow (NaN: not judged, the default)."""
        return math.nan

    def poor(self, values: np.ndarray, half_step: Any = None) -> bool:
        """The fit's error is above the verdict's limit (:data:`~droptower.identify.verdict.NOISE_RATIO`
        times the allowance)."""
        return bool(self.error_over_allowance(values, half_step) > NOISE_RATIO)

    # -------------------------------------------------------------- common
    def residuals(self, rows: np.ndarray, substeps: int | None = None) -> np.ndarray:
        """(M, R) residual vectors of the parameter sets ``rows`` (M, n)."""
        return self.evaluate(np.atleast_2d(rows), substeps)

    def __call__(self, rows: np.ndarray) -> np.ndarray:
        """:meth:`residuals` (a problem is a batched residual function)."""
        return self.residuals(rows)

    def costs(self, rows: np.ndarray, batch: int = 64) -> np.ndarray:
        """Sum of squared residuals of every row, ``batch`` rows per call; inf where not finite."""
        out = []
        for a in range(0, len(rows), batch):
            with np.errstate(all="ignore"):
                out.append(row_costs(self.residuals(rows[a:a + batch])))
        return np.concatenate(out) if out else np.zeros(0)

    def with_prior(self, x0: np.ndarray, free: np.ndarray, weight: float = PRIOR_WEIGHT) -> "PriorProblem":
        """This problem with a weak prior toward ``x0`` appended (:class:`PriorProblem`)."""
        return PriorProblem(self, x0, free, weight)

    def without_prior(self, fit: Any) -> Any:
        """Deprecated: a fit's own :meth:`~droptower.identify.engine.local.LocalFit.without_prior`."""
        from droptower.identify.result import deprecated

        deprecated("Problem.without_prior(fit)", "fit.without_prior()")
        return fit.without_prior()


class PriorProblem(Problem):
    """``problem``'s residuals with a weak prior toward ``x0`` appended: ``weight`` times the
    square root of the number of clusters (tests) times each free parameter's optimised-variable
    distance from its start. It pins directions the data do not determine (the fit would
    otherwise crawl along them until its evaluation limit) and moves the others far less than
    their standard errors (the data's curvature there is larger by many orders)."""

    def __init__(self, problem: Problem, x0: np.ndarray, free: np.ndarray, weight: float):
        self.problem, self.parameters, self.counter = problem, problem.parameters, problem.counter
        self.idx = np.flatnonzero(free)
        self.variables = Variables(self.parameters, self.idx)
        self.z0 = self.variables.z(np.asarray(x0, dtype=float))
        self.weight = weight * math.sqrt(problem.n_clusters)

    @property
    def n_clusters(self) -> int:
        return self.problem.n_clusters

    @property
    def typical_rate_rad_per_s(self) -> float:
        return self.problem.typical_rate_rad_per_s

    def move_choice(self, values: np.ndarray, index: int, value: float) -> np.ndarray:
        return self.problem.move_choice(values, index, value)

    @property
    def n_prior(self) -> int:
        """Residuals the prior appends (one per free parameter)."""
        return int(self.idx.size)

    def evaluate(self, rows: np.ndarray, substeps: int | None = None) -> np.ndarray:
        """The problem's residuals, then the prior's."""
        z = self.variables.z(rows)
        return np.concatenate([self.problem.residuals(rows, substeps), self.weight * (z - self.z0)], axis=1)


class FunctionProblem(Problem):
    """A problem of any batched residual function ``residuals(rows (M, n)) -> (M, R)`` of
    parameter sets (physical values) over ``parameters``."""

    def __init__(self, parameters: list[FitVariable], residuals: Callable[[np.ndarray], np.ndarray],
                 counter: Counter | None = None):
        self.parameters, self.function = parameters, residuals
        self.counter = counter if counter is not None else Counter()

    def evaluate(self, rows: np.ndarray, substeps: int | None = None) -> np.ndarray:
        """The function's residuals of ``rows`` (counted)."""
        self.counter.evaluations += len(rows)
        return np.asarray(self.function(rows), dtype=float)


# ---------------------------------------------------------------------------- servo records
def simulate_rows(model: Model, values: np.ndarray, segments: list, which: np.ndarray,
                  counter: Counter | None = None, evaluations: int | None = None,
                  substeps: int | None = None) -> list[np.ndarray]:
    """Torque of parameter set ``values[r]`` on segment ``segments[which[r]]`` for every row r
    (N*m; NaN for a parameter set the core refuses: :func:`admissible_couplings`).

    Rows sharing a time step and of similar length go to the core in one batched call
    (shorter histories are padded by holding their last angle). A model with ``substeps`` > 1
    is integrated on a step that many times finer (the angle linear between samples, as the
    core assumes anyway), so that its parameters do not absorb the discretisation of the
    data's sample rate. Returns one (N_s,) array per row.
    """
    values = np.atleast_2d(np.asarray(values, dtype=float))
    which = np.asarray(which, dtype=np.int64)
    substeps = int(substeps or model.substeps)
    unique, inverse = np.unique(values, axis=0, return_inverse=True)
    coupling, good = admissible_couplings(model, unique)
    out: list[np.ndarray | None] = [None] * len(which)
    lengths = np.array([segments[s].n for s in which])
    if coupling is None:
        out = [np.full(n, np.nan) for n in lengths]
        if counter is not None:
            counter.evaluations += values.shape[0] if evaluations is None else evaluations
        return out  # type: ignore[return-value]
    params = coupling.params[np.ravel(inverse)] if coupling.n_sets > 1 else np.repeat(coupling.params, len(which), 0)
    refused = ~good[np.ravel(inverse)]
    for dt in sorted({segments[s].dt_s for s in which}):
        rows = np.flatnonzero([segments[s].dt_s == dt for s in which])
        rows = rows[np.argsort(lengths[rows], kind="stable")]
        # rows of similar length share a call: padding costs at most PAD_FACTOR - 1
        groups, first = [], 0
        for i in range(1, rows.size + 1):
            if i == rows.size or lengths[rows[i]] > PAD_FACTOR * lengths[rows[first]]:
                groups.append(rows[first:i])
                first = i
        for group in groups:
            n_max = int(lengths[group].max())
            angles = np.empty((group.size, n_max))
            for i, r in enumerate(group):
                a = segments[which[r]].angle_rad
                angles[i, :a.size] = a
                angles[i, a.size:] = a[-1]
            if substeps > 1:  # the same piecewise-linear angle, integrated on a finer step
                fine = np.arange(1, n_max * substeps + 1) / substeps - 1.0
                angles = np.array([np.interp(fine, np.arange(n_max), row, left=0.0) for row in angles])
            check_budget()  # a fit stops within one core call of its time budget (.budget)
            batch = coupling.with_params(params[group])
            # the torque alone: the energy records change no torque and cost up to half of a cheap
            # coupling's call (a spring and a dashpot; tests/test_rheology_passivity.py checks the torque)
            torque = batch.simulate(angles, dt / substeps, record_energy=False).torque_nm[:, substeps - 1::substeps]
            for i, r in enumerate(group):
                out[r] = torque[i, :lengths[r]] if not refused[r] else np.full(lengths[r], np.nan)
            if counter is not None:
                counter.core_calls += 1
    if counter is not None:
        counter.evaluations += values.shape[0] if evaluations is None else evaluations
    return out  # type: ignore[return-value]


class ServoProblem(Problem):
    """Servo records bound to a family: the model's torque minus the measured one over each
    segment's compared samples (N*m), the segments concatenated.

    ``per_segment`` (S, n): each segment's own values of the parameters that are not ``free``
    (Heine & Plagemann's (2014) amplitude-dependent parameters while the frequency-dependent
    ones are fitted); the free ones are shared. Without it every row's values hold on every
    segment.
    """

    def __init__(self, model: Model, segments: list, *, per_segment: np.ndarray | None = None,
                 free: np.ndarray | None = None, counter: Counter | None = None):
        self.model, self.segments, self.parameters = model, segments, model.parameters
        self.per_segment = None if per_segment is None else np.array(per_segment, dtype=float)
        n = len(self.parameters)
        self.free = np.ones(n, bool) if free is None else np.asarray(free, bool)
        self.counter = counter if counter is not None else Counter()

    @property
    def n_clusters(self) -> int:
        return len(self.segments)

    @property
    def groups(self) -> np.ndarray:
        return np.concatenate([np.full(int(s.compared.sum()), i) for i, s in enumerate(self.segments)])

    @property
    def substeps(self) -> int:
        return int(self.model.substeps)

    @property
    def typical_rate_rad_per_s(self) -> float:
        """The RMS angular rate of the records (rad/s)."""
        return float(np.sqrt(np.mean(np.concatenate([np.diff(g.angle_rad) ** 2 / g.dt_s ** 2 for g in self.segments]))))

    def move_choice(self, values: np.ndarray, index: int, value: float) -> np.ndarray:
        """The family's move to another of a parameter's few values (its ``move_choice``)."""
        return self.model.move_choice(values, index, value, self.typical_rate_rad_per_s)

    def torques(self, rows: np.ndarray, substeps: int | None = None) -> list[list[np.ndarray]]:
        """Torque (N*m) of each parameter set ``rows`` (M, n) on every segment, one core call:
        ``out[m][s]`` (N_s,)."""
        rows = np.atleast_2d(rows)
        n_seg, m = len(self.segments), rows.shape[0]
        if self.per_segment is None:
            values = np.repeat(rows, n_seg, axis=0)
        else:
            idx = np.flatnonzero(self.free)
            values = np.repeat(self.per_segment[None, :, :], m, axis=0)  # (M, S, n)
            values[:, :, idx] = rows[:, None, idx]
            values = values.reshape(-1, len(self.parameters))
        flat = simulate_rows(self.model, values, self.segments, np.tile(np.arange(n_seg), m), self.counter, m,
                             substeps)
        return [flat[i * n_seg:(i + 1) * n_seg] for i in range(m)]

    def evaluate(self, rows: np.ndarray, substeps: int | None = None) -> np.ndarray:
        """(M, R) torque residuals (N*m) of the parameter sets ``rows``."""
        return np.array([servo_residual(self.segments, per_set) for per_set in self.torques(rows, substeps)])


# ---------------------------------------------------------------------------- drop tests
@dataclass(frozen=True)
class DropFitSettings:
    """substeps: integration steps per sample; torque_weight: weight of the torque residual
    against the angle's (0: angle only); conditioning: (ramp_s, hold_s) of the rig's preload
    conditioning the coupling undergoes before each drop, or None (virgin coupling);
    holdout_fraction: share of the tests held out; max_nfev: optimiser evaluation limit (0:
    20 per parameter + 20); seed: of the random starting points."""

    substeps: int = 1
    torque_weight: float = 0.5
    conditioning: tuple[float, float] | None = (PRELOAD_RAMP_S, PRELOAD_HOLD_S)  # the rig file's defaults
    holdout_fraction: float = HOLDOUT_FRACTION
    max_nfev: int = 0
    seed: int = 0


class DropProblem(Problem):
    """The fitting tests of a campaign bound to a family: parameter sets -> residuals, in one call.

    The residual is the angle over each test's compared window (and the torque where the log
    has it, weighted by ``torque_weight``), each test's part divided by its peak and by the
    square root of its sample count, so that small drops count as much as large ones. Every
    test is re-simulated from its impact (:mod:`droptower.identify.lever`) on a coupling in the
    state the rig's conditioning leaves it in.
    """

    def __init__(self, family: Any, decays: list, settings: DropFitSettings, counter: Counter | None = None):
        self.family, self.decays, self.settings = family, decays, settings
        dts = {round(d.dt_s, 15) for d in decays}
        if len(dts) > 1:
            raise DroptowerError(f"the logs differ in sample rate ({', '.join(f'{1 / d:.6g}' for d in sorted(dts))} Hz); "
                                 "identify them in groups of one rate")
        self.dt_s = decays[0].dt_s
        n = max(d.time_s.size for d in decays)
        self.times = np.array([np.pad(d.time_s, (0, n - d.time_s.size), mode="edge") for d in decays])
        self.mask = np.array([np.arange(n) < d.time_s.size for d in decays])
        self.angle = np.array([np.pad(d.angle_rad, (0, n - d.time_s.size)) for d in decays])
        self.torque = np.array([np.pad(d.torque_nm, (0, n - d.time_s.size)) if d.torque_nm is not None
                                else np.zeros(n) for d in decays])
        self.has_torque = np.array([d.torque_nm is not None for d in decays])
        self.inertia = np.array([d.inertia_kgm2 for d in decays], dtype=float)
        self.rate0 = np.array([d.rate0_rad_per_s for d in decays], dtype=float)
        counts = self.mask.sum(axis=1)
        self.w_angle = 1.0 / (np.array([d.amplitude_rad for d in decays]) * np.sqrt(counts))
        t_amp = np.array([d.torque_amplitude_nm if d.torque_nm is not None else 1.0 for d in decays])
        self.w_torque = np.where(self.has_torque, settings.torque_weight, 0.0) / (t_amp * np.sqrt(counts))
        # the identification's one count of evaluations: problems made from this one (the
        # search's tests, the family without its deferred part) share it
        self.counter = counter if counter is not None else Counter()
        #: the test each residual belongs to (angle part, then torque part)
        self.test_of_residual = np.concatenate([np.nonzero(self.mask)[0],
                                                np.nonzero(self.mask & self.has_torque[:, None])[0]])

    @property
    def parameters(self) -> list[FitVariable]:  # type: ignore[override]
        return self.family.parameters

    @property
    def n_clusters(self) -> int:
        return len(self.decays)

    @property
    def groups(self) -> np.ndarray:
        return self.test_of_residual

    @property
    def substeps(self) -> int:
        return int(self.settings.substeps)

    @property
    def typical_rate_rad_per_s(self) -> float:
        """The median rate (rad/s) the impacts gave the lever."""
        return float(np.median([abs(d.rate0_rad_per_s) for d in self.decays]))

    def without_deferred(self) -> "DropProblem":
        """The tests bound to the family without its deferred part (its ``without_branch``)."""
        return self.with_family(self.family.without_branch())

    def basin_moves(self, values: np.ndarray | None, free: np.ndarray) -> np.ndarray:
        """The family's moves into the basins beside ``values`` (its ``basin_moves``)."""
        return self.family.basin_moves(values, free)

    def move_choice(self, values: np.ndarray, index: int, value: float) -> np.ndarray:
        """The family's move to another of a parameter's few values (its ``move_choice``)."""
        return self.family.move_choice(values, index, value, self.typical_rate_rad_per_s)

    def half_step(self, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Angle and torque (1, T, N) of ``values`` re-simulated on half the integration step."""
        return self.simulate(np.asarray(values)[None], 2 * self.settings.substeps)

    def error_over_allowance(self, values: np.ndarray, half_step: Any = None) -> float:
        """The RMS angle error over its allowance (:func:`~droptower.identify.verdict.drop_verdict`)."""
        return self.verdict(values, half_step=half_step)[0].error_over_noise

    def poor(self, values: np.ndarray, half_step: Any = None) -> bool:
        return self.verdict(values, half_step=half_step)[0].poor

    def verdict(self, values: np.ndarray, at_bound: list[str] | None = None, converged: bool = True,
                half_step: Any = None) -> tuple[Any, float, int]:
        """:func:`~droptower.identify.verdict.drop_verdict` of the fit ``values``."""
        fine = None if half_step is None else half_step[0][0]
        return drop_verdict(self, values, list(at_bound or []), converged, fine_angle=fine)

    def with_family(self, family: Any) -> "DropProblem":
        """The same tests bound to ``family`` (e.g. without its deferred part), the count shared."""
        return DropProblem(family, self.decays, self.settings, self.counter)

    def screening(self, n_clusters: int | None) -> "DropProblem":
        """At most ``n_clusters`` of the tests, spread over the inertias and amplitudes (this
        problem itself when it has no more): a large campaign adds no information to a search's
        screening, only cost. The count is shared."""
        decays = self.decays
        if n_clusters is None or len(decays) <= n_clusters:
            return self
        order = sorted(range(len(decays)), key=lambda i: (decays[i].inertia_kgm2, decays[i].amplitude_rad))
        picked = np.round(np.linspace(0, len(decays) - 1, n_clusters)).astype(int)
        return DropProblem(self.family, [decays[order[i]] for i in picked], self.settings, self.counter)

    def couplings(self, rows: np.ndarray) -> tuple[Coupling | None, np.ndarray]:
        """One coupling over the rows' parameter sets, and which rows are admissible
        (:func:`admissible_couplings`)."""
        return admissible_couplings(self.family, rows)

    def simulate(self, rows: np.ndarray, substeps: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Angle (rad) and torque (N*m), (M, T, N), of each parameter set (rows (M, n)) on each
        test (T); NaN for a row the core refuses."""
        check_budget()  # a fit stops within one core call of its time budget (.budget)
        rows = np.atleast_2d(rows)
        m, t = rows.shape[0], len(self.decays)
        h = self.dt_s / int(substeps or self.settings.substeps)
        times = self.times
        coupling, good = self.couplings(rows)
        if coupling is None:
            nan = np.full((m, t, times.shape[1]), np.nan)
            return nan, nan
        state = None
        if self.settings.conditioning is not None:
            cond = hold_at(coupling, np.zeros(m), *self.settings.conditioning)
            which = np.repeat(np.arange(m), t)
            state = CouplingState(cond.values[which], cond.angle_rad[which], cond.torque_nm[which])
        batch = coupling.with_params(np.repeat(coupling.params, t, axis=0))
        inertia = np.tile(self.inertia, m)
        rate0 = np.tile(self.rate0, m)
        # each test only up to its last compared sample (a light lever's decay ends in about
        # half the heavy one's time): the steps beyond it would change none of its samples
        n_steps = np.tile(np.ceil(times.max(axis=1) / h).astype(np.int64) + 1, m)
        angle, torque = free_decay(batch, inertia, rate0, n_steps, h, state)
        grid = np.tile(times, (m, 1))
        a = at_times(angle, h, grid).reshape(m, t, -1)
        q = at_times(torque, h, grid).reshape(m, t, -1)
        a[~good] = np.nan
        q[~good] = np.nan
        self.counter.evaluations += m
        self.counter.core_calls += 1
        return a, q

    def evaluate(self, rows: np.ndarray, substeps: int | None = None) -> np.ndarray:
        """(M, R) weighted residual vectors (angle part, then torque part for tests with torque)."""
        return self.weighted(*self.simulate(rows, substeps))

    def weighted(self, a: np.ndarray, q: np.ndarray) -> np.ndarray:
        """(M, R) weighted residual vectors of simulated angles and torques (M, T, N)."""
        ra = ((a - self.angle[None]) * self.w_angle[None, :, None])[:, self.mask]
        sel = self.mask & self.has_torque[:, None]
        rq = ((q - self.torque[None]) * self.w_torque[None, :, None])[:, sel]
        return np.concatenate([ra, rq], axis=1)
