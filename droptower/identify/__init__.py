"""Identification of the source papers' coupling models from imposed-angle / measured-torque data.

- :mod:`.data`: records -> :class:`Segment` (SI, constant step, checked);
- :mod:`.cycles`: turning points, steady sine blocks, their lab evaluation;
- :mod:`.fit`: bounded trust-region-reflective least squares with batched Jacobians;
- :mod:`.families`: one module per model family (parameters, bounds, coupling, and its staged
  strategy), the shared stages in :mod:`.families.stages`;
- :mod:`.strategies`: :func:`identify` binds a family to the data and runs its strategy;
- :mod:`.compare`: :func:`compare_models` fits several families, each within a time budget
  (:mod:`.budget`), and ranks them;
- :mod:`.report`: JSON / text reports, comparison tables, plots.

Example::

    from droptower.identify import identify, segments_from_files
    data = segments_from_files(["sweep.csv", "ramps.csv"])
    result = identify("zerodim6", data, holdout=segments_from_files(["random.csv"]))
    print(result.parameters, result.fit.nrmse, result.holdout.nrmse)
    ranked = compare_models(data, ["zerodim6", "elastoslide", "pfeffer"], budget_s=60.0)
    print(ranked.ranking, ranked.exit_code())
"""
from droptower.identify.compare import Comparison, compare_models
from droptower.identify.data import Segment, make_segment, segments_from_files
from droptower.identify.families import FAMILIES
from droptower.identify.fit import FitResult, Identification, Metrics
from droptower.identify.strategies import identify

__all__ = ["Comparison", "FAMILIES", "FitResult", "Identification", "Metrics", "Segment", "compare_models", "identify", "make_segment",
           "segments_from_files"]
