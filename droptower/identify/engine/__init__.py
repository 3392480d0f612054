"""The identification engine: one problem, one local fit, one search, for servo records and
drop tests alike (laid out as lmfit's ``Minimizer`` owns its loop and SciPy returns one
``OptimizeResult`` from every solver; docs/guide/identification.md#the-engine).

- :mod:`.problem`: :class:`Problem` (parameter sets -> residual vectors in one batched call,
  the clusters of the residuals, the count of evaluations, the one fallback for rows the core
  refuses), :class:`ServoProblem`, :class:`DropProblem`, :class:`FunctionProblem`;
- :mod:`.local`: :func:`local_fit`, bounded trust-region-reflective least squares returning
  one :class:`LocalFit` (values, cost, residual, Jacobian, status, evaluations; covariance,
  standard errors, the integration step's bias);
- :mod:`.search`: :func:`run_search`, which owns its whole loop (screen -> local fits -> refine ->
  basin moves -> escalate -> loose prior) as a :class:`SearchPolicy` declares it.

The verdict on a fit is :mod:`droptower.identify.verdict`'s; the families contribute only the
hooks :class:`~droptower.identify.families.base.Family` declares.
"""
from droptower.identify.engine.local import LocalFit, local_fit
from droptower.identify.engine.problem import (Counter, DropFitSettings, DropProblem, FitVariable, FunctionProblem,
                                               Problem, ServoProblem)
from droptower.identify.engine.search import SearchPolicy, SearchResult, run_search

__all__ = ["Counter", "DropFitSettings", "DropProblem", "FitVariable", "FunctionProblem", "LocalFit", "Problem",
           "SearchPolicy", "SearchResult", "ServoProblem", "local_fit", "run_search"]
