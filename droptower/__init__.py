"""droptower: a virtual drop-tower impact rig and parameter extractor for elastomer couplings.

Data flows one way: config -> model (:mod:`droptower.rheology`) -> simulation
(:mod:`droptower.rig`, :mod:`droptower.servo`) -> log (:mod:`droptower.io`) -> extraction
(:mod:`droptower.extract`) -> map (:mod:`droptower.maps`) -> comparison. SI units inside.

The names a user needs first are here, one import away (``import droptower as dt``;
``dt.load_coupling("rapp2022_nr60")``); every other public name lives in its package's
``__all__``. They are imported on first use (numba is slow to import), so commands that only
read logs start fast.
"""
from __future__ import annotations

from droptower import _moved
from droptower.errors import DroptowerError
from droptower.lazy_names import lazy_names

_moved.install()  # the old import paths of renamed modules, with a DeprecationWarning

#: the package version (pyproject.toml reads it from here: one definition)
__version__ = "0.1.0"

#: the curated namespace: name -> (module, name there), imported on first use. The functions
#: ``extract``, ``identify`` and ``design`` share their names with subpackages (``droptower.extract``,
#: ``droptower.identify``, ``droptower.design``), which importing either binds here, so they are
#: reached as ``from droptower.identify import identify``, ``from droptower.design import design``;
#: here servo identification is ``identify_from_servo_records``, the pair of ``identify_from_drop_tests``.
_LAZY: dict[str, tuple[str, str]] = {
    # couplings
    "Coupling": ("droptower.rheology", "Coupling"),
    "CouplingState": ("droptower.rheology", "CouplingState"),
    "load_coupling": ("droptower.rheology", "load_coupling"),
    # the drop tower
    "load_rig": ("droptower.rig", "load_rig"),
    "load_doe": ("droptower.rig", "load_doe"),
    "DropTest": ("droptower.rig", "DropTest"),
    "simulate": ("droptower.rig", "simulate"),
    "plan": ("droptower.rig", "plan"),
    # logs and extraction
    "read_log": ("droptower.io", "read_log"),
    "extract_file": ("droptower.extract", "extract_file"),
    "ExtractSettings": ("droptower.extract", "Settings"),
    # campaigns, maps, validation, design
    "run_campaign": ("droptower.campaign", "run_campaign"),
    "CampaignRun": ("droptower.campaign", "CampaignRun"),
    "read_results": ("droptower.maps", "read_results"),
    "fit_map": ("droptower.maps", "fit_map"),
    "MapFit": ("droptower.maps", "MapFit"),
    "run_sweeps": ("droptower.compare", "run_sweeps"),
    "compare_with_servo": ("droptower.compare", "compare_with_servo"),
    "validate": ("droptower.compare", "validate"),
    "MapValidation": ("droptower.compare", "MapValidation"),
    "design_campaign": ("droptower.design", "design_campaign"),
    # the servo bench
    "run_grid": ("droptower.servo", "run_grid"),
    "run_records": ("droptower.servo", "run_records"),
    # identification and export
    "make_segment": ("droptower.identify", "make_segment"),
    "segments_from_files": ("droptower.identify", "segments_from_files"),
    "read_decays": ("droptower.identify.droplogs", "read_decays"),
    "read_drop_tests": ("droptower.identify", "read_drop_tests"),
    "identify_from_servo_records": ("droptower.identify", "identify"),
    "identify_from_drop_tests": ("droptower.identify", "identify_from_drop_tests"),
    "identify_drops": ("droptower.identify.dropfit", "identify_drops"),
    "compare_models": ("droptower.identify", "compare_models"),
    "Comparison": ("droptower.identify", "Comparison"),
    "Identification": ("droptower.identify", "Identification"),
    "Parameters": ("droptower.identify", "Parameters"),
    "Parameter": ("droptower.identify", "Parameter"),
    "build_fmu": ("droptower.fmu", "build_fmu"),
}

__all__ = ["DroptowerError", "__version__", *_LAZY]  # the table above is the one list of names


#: names of release 0.1 -> their names now, answered with a DeprecationWarning (removed in the next release)
_RENAMED = {"validate_map": "compare_with_servo"}

_lazy_getattr, __dir__ = lazy_names(__name__, _LAZY, globals())


def __getattr__(name: str) -> object:
    """A curated name on first use (:data:`_LAZY`); an old name of :data:`_RENAMED` with a warning."""
    if name in _RENAMED:
        from droptower.deprecation import warn_deprecated

        warn_deprecated(f"droptower.{name}", f"droptower.{_RENAMED[name]}")
        return _lazy_getattr(_RENAMED[name])
    return _lazy_getattr(name)
