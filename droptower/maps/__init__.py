"""Characteristic maps of Rapp et al. 2022 (eq. 19 stiffness, eq. 20 damping; docs/theory.md#map).

``fit_map(results)`` fits both equations to a results table (the extraction's results file,
a campaign's ``results.parquet``, or the paper's Table 4) and returns a :class:`MapFit`, which predicts
stiffness and damping ratio, tells whether a point is inside the measured range, and reads and
writes ``map.json``.
"""
from droptower.maps.fit import fit_map
from droptower.maps.mapfit import FitStats, MapFit, MapRange
from droptower.maps.results import ExcludedTest, read_results, select_tests

__all__ = ["ExcludedTest", "FitStats", "MapFit", "MapRange", "fit_map", "read_results", "select_tests"]
