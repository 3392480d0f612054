"""Servo records' least-squares stages: a family fitted to segments by the engine's one local fit.

:func:`least_squares_fit` binds a family to servo records (:class:`~droptower.identify.engine.problem.ServoProblem`),
runs :func:`~droptower.identify.engine.local.local_fit` (SciPy's trust-region-reflective
method on every parameter's normalised variable, the Jacobian's columns in ONE call of the
core) and reports the stage as a :class:`FitResult`: the values, their standard errors (the
lag-1 inflated covariance plus the integration step's bias), and the quality as the
zero-dimensional model paper reports it: the RMSE of the torque normalised by the largest
measured |torque| (``nrmse``). The engine's names (:class:`FitVariable`, :class:`Counter`,
:func:`clip_to_bounds`, ...) are importable from here as before.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from droptower.identify.data import Segment
from droptower.identify.engine.local import NON_IDENTIFIABLE, LocalFit, local_fit
from droptower.identify.engine.problem import (PAD_FACTOR, REFUSED_RESIDUAL, Counter, FitVariable, FunctionProblem,
                                               Model, ServoProblem, at_bounds, check_in_bounds, clip_to_bounds,
                                               finite_residuals, one_blas_thread, row_costs, simulate_rows)
from droptower.identify.result import Metrics, metrics, servo_residual
from droptower.identify.verdict import step_error

__all__ = ["Counter", "FitResult", "FitVariable", "Metrics", "Model", "NON_IDENTIFIABLE", "PAD_FACTOR",
           "REFUSED_RESIDUAL", "at_bounds", "batch_search", "check_in_bounds", "clip_to_bounds", "finite_residuals",
           "least_squares_fit", "metrics", "one_blas_thread", "row_costs", "simulate", "simulate_rows", "stage_result"]


def simulate(model: Model, values: np.ndarray, segments: list[Segment], counter: Counter | None = None
             ) -> list[list[np.ndarray]]:
    """Torque of each parameter set (rows of ``values``) on every segment: ``out[m][s]`` (N_s,)."""
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


def stage_result(problem: ServoProblem, sol: LocalFit, stage: str, started: float) -> FitResult:
    """The :class:`FitResult` of the local fit ``sol`` of ``problem`` (the stage ``stage``,
    begun at ``started``, :func:`time.perf_counter` s): the metrics on the fitting data, the
    standard errors (lag-1 inflated, the integration step's bias added) and the model's own
    discretisation error at its step (:func:`~droptower.identify.verdict.step_error`); its
    evaluations: every one ``problem`` counted, these included."""
    segments = problem.segments
    m = metrics(segments, problem.torques(sol.values[None, :])[0])
    # the integration step's bias (the zero-dimensional model paper's records are sampled coarser than the bench
    # integrates): the parameters' shift when the model is integrated on half the step,
    # Richardson-scaled for the first-order error of the core's rate-dependent elements
    fine = problem.residuals(sol.values[None, :], 2 * problem.substeps)[0]
    std = sol.std_error(m.residual_lag1, extra_z=sol.step_bias_z(fine))
    counter = problem.counter
    return FitResult(stage, [p.name for p in problem.parameters], sol.values, sol.free, std, sol.at_bounds, m,
                     sol.nfev, sol.njev, counter.evaluations,
                     counter.core_calls, time.perf_counter() - started, sol.converged, sol.message,
                     sol.non_identifiable, step_error(fine, sol.residual))


@one_blas_thread
def least_squares_fit(model: Model, segments: list[Segment], initial: np.ndarray, *, free: np.ndarray | None = None,
                      stage: str = "joint", max_nfev: int | None = None, tol: float = 1e-7,
                      per_segment: np.ndarray | None = None) -> FitResult:
    """Fit the free parameters of ``model`` to ``segments`` from ``initial`` (physical values).

    Trust-region reflective least squares (:func:`~droptower.identify.engine.local.local_fit`)
    on the sum over segments of (model - measured)^2 over the compared samples
    (:class:`~droptower.identify.engine.problem.ServoProblem`). ``per_segment`` (S, n): each
    segment's own values of the fixed parameters (Heine & Plagemann's (2014) amplitude-dependent
    parameters while its frequency-dependent ones are fitted); the free ones are shared.
    ``max_nfev`` (0 or None: 20 per free parameter + 20) bounds the optimiser's function
    evaluations; reaching it means "not converged".
    """
    started = time.perf_counter()
    free = np.ones(len(model.parameters), bool) if free is None else np.asarray(free, bool)
    problem = ServoProblem(model, segments, per_segment=per_segment, free=free)
    sol = local_fit(problem, initial, free, tol=tol, max_nfev=max_nfev)
    return stage_result(problem, sol, stage, started)


def batch_search(model: Model, segments: list[Segment], candidates: np.ndarray,
                 counter: Counter | None = None) -> tuple[int, np.ndarray]:
    """Sum of squared torque errors of every candidate parameter set (rows), in one core call.

    Returns the index of the best candidate and all the costs (inf for a candidate the core
    refused on any compared sample: :func:`row_costs`).
    """
    torques = simulate(model, candidates, segments, counter)
    costs = np.concatenate([row_costs(servo_residual(segments, per)) for per in torques])
    return int(np.argmin(costs)), costs


def fit_rows(parameters: list[FitVariable], initial: np.ndarray, residuals: Callable[[np.ndarray], np.ndarray], *,
             free: np.ndarray | None = None, max_nfev: int | None = None, tol: float = 1e-7) -> LocalFit:
    """Deprecated: :func:`~droptower.identify.engine.local.local_fit` on a
    :class:`~droptower.identify.engine.problem.FunctionProblem` (removed in the next release)."""
    import warnings

    warnings.warn("droptower.identify.fit.fit_rows is deprecated and will be removed in the next release: use "
                  "droptower.identify.engine.local_fit(FunctionProblem(parameters, residuals), initial, free)",
                  DeprecationWarning, stacklevel=2)
    return local_fit(FunctionProblem(parameters, residuals), initial, free, tol=tol, max_nfev=max_nfev)


def __getattr__(name: str) -> object:
    """Deprecated names: ``Identification`` (import it from :mod:`droptower.identify.result`,
    where it is defined) and ``RowsFit`` (now :class:`~droptower.identify.engine.local.LocalFit`);
    removed in the next release."""
    import warnings

    if name == "Identification":
        from droptower.identify.result import Identification

        warnings.warn("droptower.identify.fit.Identification is deprecated: import Identification from "
                      "droptower.identify (or droptower.identify.result)", DeprecationWarning, stacklevel=2)
        return Identification
    if name == "RowsFit":
        warnings.warn("droptower.identify.fit.RowsFit is deprecated: it is droptower.identify.engine.LocalFit",
                      DeprecationWarning, stacklevel=2)
        return LocalFit
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
