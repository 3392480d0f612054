"""Characteristic maps of Rapp et al. 2022 (eq. 19 stiffness, eq. 20 damping; docs/theory.md#map).

``fit_map(results)`` fits both equations to a results table (the extraction's results file,
a campaign's ``results.parquet``, or the paper's Table 4) and returns a :class:`MapFit`, which predicts
stiffness and damping ratio, tells whether a point is inside the measured range, and reads and
writes ``map.json``. ``results_from_logs(folder)`` extracts a lab's folder of logs into such a
table; ``coverage_notes`` names what the map does not cover (a fixture or condition whose every
test was left out, with the drop mass that would avoid its double impacts; a temperature span).
"""
from droptower.maps.coverage import TEMPERATURE_SPAN_K, coverage_notes, double_impact_advice
from droptower.maps.fitting import fit_map
from droptower.maps.fromlogs import results_from_logs
from droptower.maps.mapfit import FitStats, MapFit, MapRange
from droptower.maps.results import ExcludedTest, read_results, select_tests

__all__ = ["ExcludedTest", "FitStats", "MapFit", "MapRange", "TEMPERATURE_SPAN_K", "coverage_notes",
           "double_impact_advice", "fit_map", "read_results", "results_from_logs", "select_tests"]
