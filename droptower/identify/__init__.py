"""Identification of the source papers' coupling models from imposed-angle / measured-torque data.

- :mod:`.data`: records -> :class:`Segment` (SI, constant step, checked);
- :mod:`.cycles`: turning points, steady sine blocks, their lab evaluation;
- :mod:`.engine`: the one engine of servo and drop-test identification: a problem (batched
  residuals), one local fit (bounded trust-region-reflective least squares with batched
  Jacobians), one search with a declared policy; :mod:`.verdict` judges its fits;
- :mod:`.fit`: the servo records' least-squares stages on the engine's local fit;
- :mod:`.families`: one module per model family (parameters, bounds, coupling, and its staged
  strategy), the shared stages in :mod:`.families.stages`;
- :mod:`.strategies`: :func:`identify` binds a family to the data and runs its strategy;
- :mod:`.ranking`: :func:`compare_models` fits several families, each within a time budget
  (:mod:`.budget`), and ranks them;
- :mod:`.report`: JSON / text reports, comparison tables, plots;
- :mod:`.result`: :class:`Identification`, the one result type of servo and drop-test
  identification, with lmfit-like :class:`Parameters`;
- :mod:`.drop_campaign`: :func:`read_drop_tests` and :func:`identify_from_drop_tests`, a model
  from drop-test logs in one call (:mod:`.dropfit` the fit, :mod:`.dropreport` its report and
  servo prediction).

Example::

    from droptower.identify import identify, segments_from_files
    data = segments_from_files(["sweep.csv", "ramps.csv"])
    result = identify("zerodim6", data, holdout=segments_from_files(["random.csv"]))
    print(result.summary())  # or result.to_dict(), result.params.to_frame()
    ranked = compare_models(data, ["zerodim6", "elastoslide", "pfeffer"], budget_s=60.0)
    print(ranked.ranking, ranked.exit_code())
"""
from droptower.identify.ranking import Comparison, compare_models
from droptower.identify.data import Segment, make_segment, segments_from_files
from droptower.identify.drop_campaign import DropCampaign, identify_from_drop_tests, read_drop_tests
from droptower.identify.families import FAMILIES
from droptower.identify.fit import FitResult
from droptower.identify.result import Metrics
from droptower.identify.result import RESULT_KEYS, SUMMARY_SECTIONS, Identification, Parameter, Parameters
from droptower.identify.strategies import identify
from droptower.identify import dropreport, report  # noqa: E402,F401 (they register the result's formats)

__all__ = ["Comparison", "DropCampaign", "FAMILIES", "FitResult", "Identification", "Metrics", "Parameter", "Parameters",
           "RESULT_KEYS", "SUMMARY_SECTIONS", "Segment", "compare_models", "identify", "identify_from_drop_tests",
           "make_segment", "read_drop_tests", "segments_from_files"]
