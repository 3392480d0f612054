"""Validation of characteristic maps: against servo-hydraulic sweeps (Rapp et al. 2022, Fig. 14,
docs/theory.md#servo, #damping-measures) and against a measured map such as Rapp et al. 2022, Table 4.

- :mod:`.servo_points`: the docs/theory.md#servo sweeps on the virtual servo bench, or measured servo
  results from a table;
- :mod:`.map_vs_servo`: :func:`compare_with_servo` (a :class:`ServoComparison`), map vs servo points, deviations inside and outside the measured range,
  damping compared like with like (the drop tower's d_ratio);
- :mod:`.fig14`: the four panels of Rapp et al. 2022, Fig. 14;
- :mod:`.reference_map`: a campaign and its map vs a measured map (Table 4);
- :mod:`.model_map`: the model-based map of an identified coupling beside the paper's (docs/routes.md),
  :mod:`.model_map_plots` its figures; :func:`.map_vs_servo.validate_routes` both routes vs the bench;
- :mod:`.validate`: :func:`validate`, all of it in one call with a printable, convertible result.

Downstream of maps, servo and rheology; only the CLI and ``analysis/`` import it.
"""
from droptower.compare.reference_map import compare_reference, format_comparison, read_reference
from droptower.compare.servo_points import ServoPoints, read_servo_results, run_sweeps, sweep_points
from droptower.compare.validate import MapValidation, validate
from droptower.compare.map_vs_servo import ServoComparison, compare_with_servo, format_summary
from droptower.deprecation import moved_names

__all__ = ["MapValidation", "ServoComparison", "ServoPoints", "compare_reference", "compare_with_servo",
           "format_comparison", "format_summary", "read_reference", "read_servo_results", "run_sweeps", "sweep_points",
           "validate"]

#: the names of release 0.1, answered with a DeprecationWarning (removed in the next release)
__getattr__ = moved_names(__name__, {"Validation": "ServoComparison", "validate_map": "compare_with_servo"}, globals())
