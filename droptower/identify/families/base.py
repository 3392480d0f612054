"""The base of the model families: a parameter vector <-> a coupling of the rheological core.

Each family names its parameters (unit as suffix), scales their bounds and a first guess to
the data (:class:`~droptower.identify.data.DataScale`), and builds a coupling of the
rheological core from a parameter vector. :meth:`Family.batch` builds ONE coupling whose
parameter sets (rows of ``Coupling.params``) are many parameter vectors: the fitting engine
simulates them all in one call of the core.
"""
from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from droptower.errors import DroptowerError
from droptower.identify.data import DataScale
from droptower.identify.engine.problem import FitVariable, clip_to_bounds
from droptower.identify.families.compiled import stacked
from droptower.rheology import Coupling, parse_coupling


class Family:
    """Base of the model families.

    kind: the name on the command line; title, source: for reports and coupling files;
    OPTIONS: family options (the ``[options]`` table of an init TOML file) with their defaults.
    """

    kind: ClassVar[str] = ""
    title: ClassVar[str] = ""
    source: ClassVar[str] = ""
    OPTIONS: ClassVar[dict[str, Any]] = {}
    #: Parameters of a part the drop-test fit switches off in its first search and frees in the
    #: wider one after a poor verdict (:meth:`without_branch`, :meth:`branch_off`); none by default.
    DEFERRED: ClassVar[tuple[str, ...]] = ()

    def __init__(self, scale: DataScale, options: dict[str, Any] | None = None):
        self.scale = scale
        options = dict(options or {})
        unknown = set(options) - set(self.OPTIONS) - set(COMMON_OPTIONS)
        if unknown:
            known = sorted(set(self.OPTIONS) | set(COMMON_OPTIONS))
            raise DroptowerError(f"unknown option(s) {', '.join(sorted(unknown))} for family {self.kind} "
                                 f"(known: {', '.join(known)})")
        self.options = {**COMMON_OPTIONS, **self.OPTIONS, **options}
        self.parameters: list[FitVariable] = self._parameters()

    # -------------------------------------------------------------- per family
    def _parameters(self) -> list[FitVariable]:  # pragma: no cover - abstract
        raise NotImplementedError

    def guess(self) -> np.ndarray:  # pragma: no cover - abstract
        """A first guess from the data's scale (physical values)."""
        raise NotImplementedError

    def elements(self, v: np.ndarray) -> list[dict[str, Any]]:  # pragma: no cover - abstract
        """The ``[[element]]`` tables of the coupling for parameter vector ``v``."""
        raise NotImplementedError

    def derived(self, v: np.ndarray) -> dict[str, float]:
        """Quantities computed from the parameters, for reports."""
        return {}

    def choices(self) -> dict[int, list[float]]:
        """Parameters that take one of a few values (index -> the values): a global search draws
        them among these instead of sampling their bounds (none by default)."""
        return {}

    # -------------------------------------------------------------- optional hooks
    # Every hook a family may offer, with the behaviour of a family that offers nothing: the
    # engine calls them on every family and never asks whether they exist.
    def without_branch(self) -> "Family":
        """The same family (the same parameters, the user's bounds kept) whose couplings leave the
        :data:`DEFERRED` part out (itself by default)."""
        return self

    def branch_off(self, v: np.ndarray) -> np.ndarray:
        """``v`` with the :data:`DEFERRED` part switched off (a copy of ``v`` by default)."""
        return np.array(v, float)

    def guess_from_readings(self, amplitude_rad: np.ndarray, frequency_hz: np.ndarray, stiffness: np.ndarray,
                            x0: np.ndarray, given: np.ndarray) -> np.ndarray:
        """A first guess from harmonic readings (amplitude rad, frequency Hz, K' + i K'' N*m/rad,
        e.g. a drop campaign's first cycles), ``x0`` kept where ``given``: ``x0`` by default (a
        family without a closed form to read them)."""
        return np.array(x0, float)

    def basin_moves(self, v: np.ndarray, free: np.ndarray) -> np.ndarray:
        """Parameter sets (rows) near the fit ``v`` in the basins beside it, tried when a fit is a
        few times the noise allowance (none by default: shape (0, n))."""
        return np.empty((0, len(self.parameters)))

    def move_choice(self, v: np.ndarray, index: int, value: float, rate_rad_per_s: float) -> np.ndarray:
        """``v`` with parameter ``index``, one of a few values (:meth:`choices`), moved to
        ``value`` where a search walks it; ``rate_rad_per_s``: the data's typical rate, for a
        family whose rate law moves with it. By default only that parameter changes."""
        out = np.array(v, float)
        out[index] = value
        return out

    def idle_parameters(self, v: np.ndarray) -> list[str]:
        """Parameters of a part switched off in ``v``, whose bounds are not bound hits (none by default)."""
        return []

    @property
    def substeps(self) -> int:
        """Integration steps per data sample (option ``substeps``)."""
        n = int(self.options["substeps"])
        if n < 1:
            raise DroptowerError(f"option substeps must be a positive integer, got {self.options['substeps']}")
        return n

    # -------------------------------------------------------------- common
    @property
    def names(self) -> list[str]:
        return [p.name for p in self.parameters]

    def initial(self) -> np.ndarray:
        return clip_to_bounds(self.parameters, self.guess())

    def coupling_data(self, v: np.ndarray, *, name: str = "", description: str = "") -> dict[str, Any]:
        """The coupling file (the dict :func:`~droptower.rheology.parse_coupling` reads) of one
        parameter vector."""
        return {"name": name or f"identified_{self.kind}", "description": description or self.title,
                "source": self.source, "units": self.scale.units, "element": self.elements(np.asarray(v, float))}

    def coupling(self, v: np.ndarray, *, name: str = "", description: str = "") -> Coupling:
        """The coupling of one parameter vector."""
        return parse_coupling(self.coupling_data(v, name=name, description=description))

    def batch(self, values: np.ndarray) -> Coupling:
        """One coupling whose parameter sets are the rows of ``values`` (M, n): the stack of each
        row's :meth:`coupling`, each distinct element validated and compiled once
        (:func:`~droptower.identify.families.compiled.stacked`: the same numbers). A family that
        builds its couplings its own way (its own :meth:`coupling`) gets the stack of those."""
        values = np.atleast_2d(values)
        if type(self).coupling is not Family.coupling:
            return Coupling.stack([self.coupling(v) for v in values])
        return stacked([self.coupling_data(v) for v in values])


#: Options every family takes: max_nfev (evaluation limit of each least-squares stage; 0: 20
#: per free parameter + 20), skip_s (seconds at each record's start left out of the fit),
#: substeps (integration steps per sample: the rig and the bench integrate finer than they
#: sample, and a model fitted on the sample step alone absorbs that step's discretisation).
COMMON_OPTIONS: dict[str, Any] = {"max_nfev": 0, "skip_s": 0.0, "substeps": 1}


def stiffness_parameter(name: str, s: DataScale, lo: float = 1e-4, hi: float = 1e3) -> FitVariable:
    return FitVariable(name, lo * s.stiffness_nm_per_rad, hi * s.stiffness_nm_per_rad)
