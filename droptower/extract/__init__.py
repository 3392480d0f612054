"""Stiffness and damping from drop-test logs (Rapp et al. 2022, eq. 13-18, docs/theory.md#decay, #extraction, #damping-measures).

``extract(signals, inertia_kgm2=..., window="first-cycle") -> ExtractionResult`` evaluates one
test given as SI :class:`~droptower.io.signals.DropSignals`; ``extract_file(path, Settings())``
reads, maps and evaluates one log file (``extract_drops`` every drop of it, with the geometry
cross-checks of :func:`geometry_checks`); :mod:`droptower.sdof` holds eq. 15, 16, 18
and the servo-comparable damping measures; :class:`SyntheticDrop` makes logs with known
stiffness and damping; :func:`droptower.extract.plot.plot_fit` draws Rapp et al. 2022, Fig. 9.
"""
from droptower.extract.extractor import extract
from droptower.extract.files import Settings, extract_drops, extract_file, result_row
from droptower.extract.geometry import geometry_checks
from droptower.extract.result import ExtractionResult
from droptower.extract.synthetic import SyntheticDrop
from droptower.extract.window import Window

__all__ = ["ExtractionResult", "Settings", "SyntheticDrop", "Window", "extract", "extract_drops", "extract_file",
           "geometry_checks", "result_row"]
