"""The engine's one local fit: bounded trust-region-reflective least squares on a problem.

:func:`local_fit` is SciPy's ``least_squares`` (method ``trf``, the zero-dimensional model
paper used MATLAB's TRF) on a :class:`~droptower.identify.engine.problem.Problem`: every
parameter is optimised in a normalised variable (its logarithm, or its value over a scale) so
that one trust region suits them all, and the forward-difference Jacobian's columns are all
evaluated in ONE call of the problem (one batched call of the core). It returns one
:class:`LocalFit` (as SciPy returns one ``OptimizeResult``): the values, the cost, the residual
and its Jacobian, the optimiser's status and evaluations, and the uncertainties computed from
them: the covariance (lag-1 inflated, or cluster-robust), standard errors and the integration
step's bias (Richardson), each written once here.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from droptower.identify.engine.problem import (FitVariable, PriorProblem, Problem, Variables, finite_residuals,
                                               one_blas_thread)

#: Singular values of the Jacobian below this fraction of the largest mark a non-identifiable combination.
NON_IDENTIFIABLE = 1e-4


@dataclass
class LocalFit:
    """The solution of :func:`local_fit`: values (all parameters, physical), the residual r and
    its Jacobian in the optimised variables (columns: free parameters), the optimiser's word.

    parameters: the optimiser's variables; free: which were fitted; at_bounds: names of fitted
    parameters on an active bound; nfev, njev: the optimiser's function and Jacobian
    evaluations; converged: a tolerance was met (not the evaluation limit); n_prior: residuals
    a prior appended (the last ones; :meth:`without_prior`).
    """

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
    n_prior: int = 0

    @property
    def x(self) -> np.ndarray:
        """The values (SciPy's name)."""
        return self.values

    @property
    def cost(self) -> float:
        """Sum of squared residuals (the prior's included, where it has one)."""
        return float(self.residual @ self.residual)

    @property
    def status(self) -> str:
        """``"converged"`` or ``"evaluation limit"``."""
        return "converged" if self.converged else "evaluation limit"

    def without_prior(self) -> "LocalFit":
        """The fit's residual and Jacobian without the prior's rows (for errors and uncertainties)."""
        k = self.n_prior
        if not k:
            return self
        return dataclasses.replace(self, residual=self.residual[:-k], jacobian=self.jacobian[:-k], n_prior=0)

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
        the integration step's bias, :meth:`step_bias_z`), added in quadrature."""
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
        scaled Jacobian with singular value below :data:`NON_IDENTIFIABLE` times the largest,
        each as {parameter name: weight} in the optimised variables (ln value or value / scale);
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


@one_blas_thread
def local_fit(problem: Problem, start: np.ndarray, free: np.ndarray | None = None, *,
              prior_weight: float | None = None, tol: float = 1e-7, max_nfev: int | None = None) -> LocalFit:
    """Bounded trust-region-reflective least squares on ``problem`` from ``start``.

    Parameters
    ----------
    problem : Problem
        Parameter sets (M, n) -> residual vectors (M, R), many at once: the forward-difference
        Jacobian's columns go to the model in ONE call. Non-finite residuals count as
        :data:`~droptower.identify.engine.problem.REFUSED_RESIDUAL` (a failed simulation is a
        terrible candidate).
    start : ndarray
        All parameters' values (their units); the fixed ones stay there.
    free : ndarray of bool, optional
        Which parameters are fitted (all by default).
    prior_weight : float, optional
        A weak prior toward ``start`` (:meth:`~droptower.identify.engine.problem.Problem.with_prior`),
        its residuals the last of the fit's (:attr:`LocalFit.n_prior`).
    tol : float
        Relative tolerance of the cost and the step (the gradient's: 1 % of it).
    max_nfev : int, optional
        The optimiser's function evaluations at most (0 or None: 20 per free parameter + 20);
        reaching it means "not converged".

    Returns
    -------
    LocalFit
    """
    free = np.ones(len(problem.parameters), bool) if free is None else np.asarray(free, bool)
    if prior_weight is not None:
        problem = problem.with_prior(start, free, prior_weight)
    parameters = problem.parameters
    x_all = np.asarray(start, dtype=float).copy()
    idx = np.flatnonzero(free)
    if idx.size == 0:
        raise ValueError("no free parameter")
    lo, hi = np.array([parameters[i].z_bounds() for i in idx]).T
    variables = Variables(parameters, idx)

    def values_of(z: np.ndarray) -> np.ndarray:
        v = x_all.copy()
        v[idx] = variables.values(z)
        return v

    def safe(rows: np.ndarray) -> np.ndarray:
        return finite_residuals(problem.residuals(rows))

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
        # row j: z + h_j e_j, the same sums as one row at a time
        rows = np.repeat(x_all[None, :], z.size, axis=0)
        rows[:, idx] = variables.values(z[None, :] + h[:, None] * np.eye(z.size))
        return ((safe(rows) - r0) / h[:, None]).T

    z0 = variables.z(x_all)
    res = least_squares(fun, z0, jac=jac, bounds=(lo, hi), method="trf", x_scale=1.0, ftol=tol, xtol=tol,
                        gtol=tol * 1e-2, max_nfev=int(max_nfev or 20 * idx.size + 20))
    hits = [parameters[i].name for i, a in zip(idx, res.active_mask) if a != 0]
    n_prior = problem.n_prior if isinstance(problem, PriorProblem) else 0
    return LocalFit(parameters, values_of(res.x), free, fun(res.x), np.asarray(res.jac), hits, int(res.nfev),
                    int(res.njev or 0), bool(res.status > 0), str(res.message), n_prior)
