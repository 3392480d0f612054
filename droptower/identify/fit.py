"""Bounded nonlinear least squares on the torque error under imposed angle histories.

The optimiser is SciPy's trust-region-reflective method (the zero-dimensional model paper used MATLAB's TRF). Every
parameter is optimised in a normalised variable (its logarithm, or its value over a scale)
so that one trust region suits them all. The Jacobian is a forward difference whose columns
are all simulated in ONE call of the core: the perturbed parameter sets are stacked on the
core's batch axis (:meth:`Coupling.stack`), together with every segment of the data, and the
core runs them at once, its rows spread over the cores (:mod:`droptower.rheology.threads`).

Quality is reported as the zero-dimensional model paper does: the RMSE of the torque normalised by the largest
measured |torque| (``nrmse``), on the fitting data and on held-out data.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable, Protocol

import numpy as np
from scipy.optimize import least_squares
from threadpoolctl import threadpool_limits

from droptower.errors import DroptowerError
from droptower.identify.budget import check as check_budget
from droptower.identify.data import Segment
from droptower.identify.result import Metrics, metrics, servo_residual
from droptower.rheology import Coupling


#: Histories up to this factor longer than the shortest of a call share it (padding waste).
PAD_FACTOR = 1.5

#: The linear algebra of a fit on ONE thread (a decorator). The cores belong to the core's
#: batched simulations; a fit's matrices are tall and narrow (residuals x parameters, e.g.
#: 50 000 x 20), which threads hardly speed up, while a BLAS thread pool whose threads wait for
#: a busy core stalls every call: the SVD that each trust-region step takes of such a Jacobian
#: took 0.03 s on one thread and 0.4 s on two with both cores busy (measured on the
#: project's 2-core machine), more than the simulations of the step.
one_blas_thread = threadpool_limits.wrap(limits=1, user_api="blas")


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
        return float(np.log(value)) if self.log else value / self.scale

    def to_value(self, z: float) -> float:
        return float(np.exp(z)) if self.log else z * self.scale

    def dvalue_dz(self, value: float) -> float:
        return value if self.log else self.scale

    def z_bounds(self) -> tuple[float, float]:
        return self.to_z(self.lower), self.to_z(self.upper)


class Model(Protocol):
    """What the fitting engine needs of a model family."""

    parameters: list[FitVariable]

    def batch(self, values: np.ndarray) -> Coupling:
        """One coupling whose parameter sets are the rows of ``values`` (M, n)."""


@dataclass
class Counter:
    """Model evaluations: parameter sets simulated over their data, and calls of the core."""

    evaluations: int = 0
    core_calls: int = 0


def simulate_rows(model: Model, values: np.ndarray, segments: list[Segment], which: np.ndarray,
                  counter: Counter | None = None, evaluations: int | None = None,
                  substeps: int | None = None) -> list[np.ndarray]:
    """Torque of parameter set ``values[r]`` on segment ``segments[which[r]]`` for every row r.

    Rows sharing a time step and of similar length go to the core in one batched call
    (shorter histories are padded by holding their last angle). A model with ``substeps`` > 1
    is integrated on a step that many times finer (the angle linear between samples, as the
    core assumes anyway), so that its parameters do not absorb the discretisation of the
    data's sample rate. Returns one (N_s,) array per row.
    """
    values = np.atleast_2d(np.asarray(values, dtype=float))
    which = np.asarray(which, dtype=np.int64)
    substeps = int(substeps or getattr(model, "substeps", 1))
    unique, inverse = np.unique(values, axis=0, return_inverse=True)
    coupling = model.batch(unique)
    params = coupling.params[np.ravel(inverse)] if coupling.n_sets > 1 else np.repeat(coupling.params, len(which), 0)
    out: list[np.ndarray | None] = [None] * len(which)
    lengths = np.array([segments[s].n for s in which])
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
                out[r] = torque[i, :lengths[r]]
            if counter is not None:
                counter.core_calls += 1
    if counter is not None:
        counter.evaluations += values.shape[0] if evaluations is None else evaluations
    return out  # type: ignore[return-value]


def simulate(model: Model, values: np.ndarray, segments: list[Segment], counter: Counter | None = None
             ) -> list[list[np.ndarray]]:
    """Torque of each parameter set (rows of ``values``) on every segment: out[m][s] (N_s,)."""
    values = np.atleast_2d(values)
    m, s = values.shape[0], len(segments)
    # one evaluation = one parameter set over all the data
    flat = simulate_rows(model, np.repeat(values, s, axis=0), segments, np.tile(np.arange(s), m), counter, m)
    return [flat[i * s:(i + 1) * s] for i in range(m)]


@dataclass
class FitResult:
    """One least-squares fit.

    values: all parameter values; free: which were fitted; std_error: standard errors of the
    fitted ones from the Jacobian (s^2 (J'J)^-1), inflated by sqrt((1 + r1)/(1 - r1)) for the
    residual's lag-1 autocorrelation r1 (an AR(1) effective sample size), NaN for fixed ones;
    at_bounds: names of fitted parameters that ended on a bound; metrics: on the fitting data;
    nfev, njev: optimiser function and Jacobian evaluations; evaluations: parameter sets
    simulated over the data (a Jacobian of n columns counts n); converged: the optimiser met a
    tolerance (not the evaluation limit); message: the optimiser's word; step_error_nm: the
    model's own discretisation error at the step it is fitted on (twice the RMS change of its
    torque when integrated on half the step: first order), an allowance beside the noise.
    """

    stage: str
    names: list[str]
    values: np.ndarray
    free: np.ndarray
    std_error: np.ndarray
    at_bounds: list[str]
    metrics: Metrics
    nfev: int
    njev: int
    evaluations: int
    core_calls: int
    time_s: float
    converged: bool
    message: str
    non_identifiable: list[dict[str, float]] = field(default_factory=list)
    step_error_nm: float = 0.0

    def params(self) -> dict[str, float]:
        return dict(zip(self.names, map(float, self.values)))

    def summary(self) -> str:
        """One line of text: the stage, its error, effort and the optimiser's word (as every
        ``summary()``; :meth:`to_dict` for the data). Read as the dict it returned in release
        0.1, it still answers with a DeprecationWarning for this release."""
        from droptower.deprecation import TextReport

        text = (f"stage {self.stage}: nRMSE {100 * self.metrics.nrmse:.3f} %, {self.nfev} steps, "
                f"{self.evaluations} evaluations, {self.time_s:.2f} s, "
                + ("converged" if self.converged else f"not converged: {self.message}"))
        return TextReport(text, self.to_dict(), "FitResult")

    def to_dict(self) -> dict:
        """JSON-ready: the stage, its free parameters, error, evaluations, time and the optimiser's word."""
        return {"stage": self.stage, "free": [n for n, f in zip(self.names, self.free) if f],
                "nrmse": self.metrics.nrmse, "nfev": self.nfev, "njev": self.njev,
                "evaluations": self.evaluations, "wall_s": self.time_s, "converged": self.converged,
                "message": self.message, "non_identifiable": self.non_identifiable}


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


@one_blas_thread
def least_squares_fit(model: Model, segments: list[Segment], initial: np.ndarray, *, free: np.ndarray | None = None,
                      stage: str = "joint", max_nfev: int | None = None, tol: float = 1e-7,
                      per_segment: np.ndarray | None = None) -> FitResult:
    """Fit the free parameters of ``model`` to ``segments`` from ``initial`` (physical values).

    Trust-region reflective least squares on the sum over segments of (model - measured)^2
    over the compared samples. The Jacobian's columns go to the core in one batched call.
    ``per_segment`` (S, n): each segment's own values of the fixed parameters (Heine & Plagemann's (2014)
    amplitude-dependent parameters while its frequency-dependent ones are fitted); the free
    ones are shared. ``max_nfev`` (0 or None: 20 per free parameter + 20) bounds the
    optimiser's function evaluations; reaching it means "not converged".
    """
    params = model.parameters
    free = np.ones(len(params), bool) if free is None else np.asarray(free, bool)
    counter = Counter()
    start = time.perf_counter()
    n_seg = len(segments)
    base = np.tile(initial, (n_seg, 1)) if per_segment is None else np.array(per_segment, dtype=float)
    idx = np.flatnonzero(free)

    def torques(rows: np.ndarray, substeps: int | None = None) -> list[list[np.ndarray]]:
        """Torque of each parameter set ``rows`` (M, n) on every segment, one core call."""
        values = np.repeat(base[None, :, :], rows.shape[0], axis=0)  # (M, S, n)
        values[:, :, idx] = rows[:, None, idx]
        flat = simulate_rows(model, values.reshape(-1, len(params)), segments, np.tile(np.arange(n_seg), rows.shape[0]),
                             counter, rows.shape[0], substeps)
        return [flat[i * n_seg:(i + 1) * n_seg] for i in range(rows.shape[0])]

    def residuals(rows: np.ndarray, substeps: int | None = None) -> np.ndarray:
        """(M, R) residual vectors of the parameter sets ``rows`` (M, n)."""
        return np.array([servo_residual(segments, per_set) for per_set in torques(rows, substeps)])

    sol = fit_rows(params, initial, residuals, free=free, max_nfev=max_nfev, tol=tol)
    m = metrics(segments, torques(sol.values[None, :])[0])
    # the integration step's bias (the zero-dimensional model paper's records are sampled coarser than the bench
    # integrates): the parameters' shift when the model is integrated on half the step,
    # Richardson-scaled for the first-order error of the core's rate-dependent elements
    fine = residuals(sol.values[None, :], 2 * int(getattr(model, "substeps", 1)))[0]
    std = sol.std_error(m.residual_lag1, extra_z=sol.step_bias_z(fine))
    # the model's own discretisation error at the step it is fitted on: twice its change on
    # half the step (first order), RMS over the compared samples
    step_error = 2.0 * float(np.sqrt(np.mean((fine - sol.residual) ** 2))) if fine.size else 0.0
    return FitResult(stage, [p.name for p in params], sol.values, free, std, sol.at_bounds, m, sol.nfev,
                     sol.njev, counter.evaluations, counter.core_calls, time.perf_counter() - start,
                     sol.converged, sol.message, sol.non_identifiable,
                     step_error if np.isfinite(step_error) else 0.0)


@dataclass
class RowsFit:
    """The solution of :func:`fit_rows`: values (all parameters, physical), the optimiser's
    word, the residual r and its Jacobian in the optimised variables (columns: free parameters)."""

    parameters: list[FitVariable]
    values: np.ndarray
    free: np.ndarray
    residual: np.ndarray
    jacobian: np.ndarray
    at_bounds: list[str]
    nfev: int
    njev: int
    converged: bool
    message: str

    def covariance_z(self, lag1: float = 0.0) -> np.ndarray:
        """s^2 (J'J)^+ in the optimised variables, inflated by sqrt((1 + r1)/(1 - r1)) for the
        residual's lag-1 autocorrelation r1 (an AR(1) effective sample size)."""
        r, jac = self.residual, self.jacobian
        dof = max(r.size - jac.shape[1], 1)
        rho = min(max(lag1, 0.0), 0.99)
        return float(r @ r) / dof * np.linalg.pinv(jac.T @ jac) * (1.0 + rho) / (1.0 - rho)

    def covariance_z_clustered(self, groups: np.ndarray) -> np.ndarray:
        """Cluster-robust (sandwich) covariance in the optimised variables: residuals within a
        group (e.g. one drop test) may be correlated in any way, e.g. by a systematic misfit
        of that test; groups are independent. (J'J)^+ (sum_g J_g' r_g r_g' J_g) (J'J)^+, scaled
        by G / (G - 1)."""
        jac, r = self.jacobian, self.residual
        labels, inverse = np.unique(groups, return_inverse=True)
        scores = np.zeros((labels.size, jac.shape[1]))
        np.add.at(scores, inverse, jac * r[:, None])
        bread = np.linalg.pinv(jac.T @ jac)
        g = labels.size
        return bread @ (scores.T @ scores) @ bread * (g / max(g - 1, 1))

    def step_bias_z(self, fine_residual: np.ndarray) -> np.ndarray:
        """The integration step's bias in the optimised variables: the parameters' shift that
        the residual on half the step (``fine_residual``) asks for, twice (Richardson, first
        order: the core's rate-dependent elements, docs/theory.md#verdict); 0 where it is not
        finite (a half-step run the core refused), so that it never turns a standard error NaN."""
        bias = 2.0 * np.linalg.lstsq(self.jacobian, -(np.asarray(fine_residual) - self.residual), rcond=None)[0]
        return np.where(np.isfinite(bias), bias, 0.0)

    def std_error(self, lag1: float = 0.0, extra_z: np.ndarray | None = None,
                  groups: np.ndarray | None = None) -> np.ndarray:
        """Standard errors of the free parameters (physical units; NaN for fixed ones): the
        larger of the AR(1)-inflated and, with ``groups``, the cluster-robust one.
        ``extra_z``: a further uncertainty per free parameter in the optimised variables (e.g.
        the integration step's bias), added in quadrature."""
        idx = np.flatnonzero(self.free)
        var = np.clip(np.diag(self.covariance_z(lag1)), 0.0, None)
        if groups is not None:
            var = np.maximum(var, np.clip(np.diag(self.covariance_z_clustered(groups)), 0.0, None))
        if extra_z is not None:
            var = var + np.asarray(extra_z) ** 2
        std = np.full(len(self.parameters), np.nan)
        std[idx] = [self.parameters[i].dvalue_dz(self.values[i]) * s for i, s in zip(idx, np.sqrt(var))]
        return std

    @property
    def non_identifiable(self) -> list[dict[str, float]]:
        """Directions in parameter space the data do not pin down: right singular vectors of the
        scaled Jacobian with singular value below ``NON_IDENTIFIABLE`` times the largest, each
        as {parameter name: weight} in the optimised variables (ln value or value / scale);
        moving the parameters along it leaves the fit unchanged."""
        idx = np.flatnonzero(self.free)
        if self.jacobian.size == 0:
            return []
        _, sv, vt = np.linalg.svd(self.jacobian, full_matrices=False)
        out = []
        for s, v in zip(sv, vt):
            if s < NON_IDENTIFIABLE * sv[0]:
                v = v / v[np.argmax(np.abs(v))]
                out.append({self.parameters[i].name: float(w) for i, w in zip(idx, v) if abs(w) > 0.05})
        return out


#: Singular values of the Jacobian below this fraction of the largest mark a non-identifiable combination.
NON_IDENTIFIABLE = 1e-4


#: The residual a least-squares optimiser sees for a sample the core refused or that diverged
#: (non-finite): a failed simulation is a terrible candidate, never a good one, and the optimiser
#: needs finite numbers. Where costs are compared (:func:`row_costs`) such a row costs inf.
REFUSED_RESIDUAL = 1e30


def finite_residuals(r: np.ndarray) -> np.ndarray:
    """``r`` with every non-finite sample replaced by :data:`REFUSED_RESIDUAL`."""
    return np.where(np.isfinite(r), r, REFUSED_RESIDUAL)


def row_costs(r: np.ndarray) -> np.ndarray:
    """Sum of squared residuals of each row of ``r`` (M, R); inf for a row with any non-finite
    sample (the one policy for rows the core refuses: :data:`REFUSED_RESIDUAL`)."""
    r = np.atleast_2d(r)
    with np.errstate(all="ignore"):
        return np.where(np.isfinite(r).all(axis=1), np.sum(np.where(np.isfinite(r), r, 0.0) ** 2, axis=1), np.inf)


@one_blas_thread
def fit_rows(parameters: list[FitVariable], initial: np.ndarray, residuals: Callable[[np.ndarray], np.ndarray], *,
             free: np.ndarray | None = None, max_nfev: int | None = None, tol: float = 1e-7) -> RowsFit:
    """Bounded trust-region-reflective least squares on ``residuals``.

    residuals(rows (M, n) physical parameter sets) -> (M, R) residual vectors: the function
    evaluates many parameter sets at once, so the forward-difference Jacobian's columns go to
    the model in ONE call. Non-finite residuals count as :data:`REFUSED_RESIDUAL` (a failed
    simulation is a terrible candidate). ``max_nfev`` (0 or None: 20 per free parameter + 20) bounds the
    optimiser's function evaluations; reaching it means "not converged".
    """
    x_all = np.asarray(initial, dtype=float).copy()
    free = np.ones(len(parameters), bool) if free is None else np.asarray(free, bool)
    idx = np.flatnonzero(free)
    if idx.size == 0:
        raise ValueError("no free parameter")
    lo, hi = np.array([parameters[i].z_bounds() for i in idx]).T

    def values_of(z: np.ndarray) -> np.ndarray:
        v = x_all.copy()
        v[idx] = [parameters[i].to_value(zi) for i, zi in zip(idx, z)]
        return v

    def safe(rows: np.ndarray) -> np.ndarray:
        return finite_residuals(residuals(rows))

    cache: dict[bytes, np.ndarray] = {}

    def fun(z: np.ndarray) -> np.ndarray:
        key = z.tobytes()
        if key not in cache:
            cache.clear()
            cache[key] = safe(values_of(z)[None, :])[0]
        return cache[key]

    def jac(z: np.ndarray) -> np.ndarray:
        r0 = fun(z)
        h = 1e-6 * (1.0 + np.abs(z))
        h = np.where(z + h > hi, -h, h)  # step inward at an upper bound
        rows = np.array([values_of(z + h[j] * np.eye(z.size)[j]) for j in range(z.size)])
        return ((safe(rows) - r0) / h[:, None]).T

    z0 = np.array([parameters[i].to_z(x_all[i]) for i in idx])
    res = least_squares(fun, z0, jac=jac, bounds=(lo, hi), method="trf", x_scale=1.0, ftol=tol, xtol=tol,
                        gtol=tol * 1e-2, max_nfev=int(max_nfev or 20 * idx.size + 20))
    at_bounds = [parameters[i].name for i, a in zip(idx, res.active_mask) if a != 0]
    return RowsFit(parameters, values_of(res.x), free, fun(res.x), np.asarray(res.jac), at_bounds, int(res.nfev),
                   int(res.njev or 0), bool(res.status > 0), str(res.message))


def batch_search(model: Model, segments: list[Segment], candidates: np.ndarray,
                 counter: Counter | None = None) -> tuple[int, np.ndarray]:
    """Sum of squared torque errors of every candidate parameter set (rows), in one core call.

    Returns the index of the best candidate and all the costs (inf for a candidate the core
    refused on any compared sample: :func:`row_costs`).
    """
    torques = simulate(model, candidates, segments, counter)
    costs = np.concatenate([row_costs(servo_residual(segments, per)) for per in torques])
    return int(np.argmin(costs)), costs


def __getattr__(name: str) -> object:
    """``Identification`` from here: deprecated (import it from :mod:`droptower.identify.result`,
    where it is defined); it is removed in the next release."""
    if name == "Identification":
        import warnings

        from droptower.identify.result import Identification

        warnings.warn("droptower.identify.fit.Identification is deprecated: import Identification from "
                      "droptower.identify (or droptower.identify.result)", DeprecationWarning, stacklevel=2)
        return Identification
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
