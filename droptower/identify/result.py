"""One result type for every identification: servo records and drop tests alike.

:class:`Parameter` is what an engineer knows from lmfit: a name, a value, its standard error,
its bounds and whether it was fitted (``vary``), with its unit (read off the name's suffix,
``k1_nm_per_rad`` -> N*m/rad). :class:`Parameters` is an ordered name -> :class:`Parameter`
mapping; it is what :class:`Identification` reports and what
:func:`~droptower.identify.identify` and :func:`~droptower.identify.identify_from_drop_tests`
accept as ``init``: finite ``min`` / ``max`` are the bounds, a varying parameter's value is its
initial value; ``vary=False`` holds a parameter of a drop-test identification at its value (the
servo strategies fit every parameter, so they refuse it).
"""
from __future__ import annotations

import copy
import math
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Iterable, Mapping

import numpy as np

from droptower.deprecation import renamed_attribute, warn_deprecated
from droptower.errors import DroptowerError

if TYPE_CHECKING:
    import pandas as pd

    from droptower.identify.data import Segment
    from droptower.rheology import Coupling

#: what :attr:`Identification.data` says: identified from servo records, or from drop tests
SERVO, DROPS = "servo records", "drop tests"


@dataclass(frozen=True)
class Metrics:
    """Torque error of a model on some data.

    rmse_nm: root mean square of (model - measured) over the compared samples;
    nrmse: rmse_nm / max |measured torque| (the zero-dimensional model paper's measure, a fraction, not percent);
    residual_lag1: lag-1 autocorrelation of the residual (near 0: white, the model explains
    all structure; near 1: systematic misfit or strongly coloured noise); n_samples.
    """

    rmse_nm: float
    nrmse: float
    residual_lag1: float
    n_samples: int
    max_torque_nm: float

    def to_dict(self) -> dict[str, float]:
        """JSON-ready: the errors with their units in their names."""
        return {"rmse_nm": self.rmse_nm, "nrmse": self.nrmse, "nrmse_percent": 100.0 * self.nrmse,
                "residual_lag1": self.residual_lag1, "n_samples": self.n_samples,
                "max_torque_nm": self.max_torque_nm}

    def as_dict(self) -> dict[str, float]:
        """Deprecated: :meth:`to_dict` (removed in the next release)."""
        deprecated("Metrics.as_dict()", "Metrics.to_dict()")
        return self.to_dict()


def deprecated(old: str, new: str) -> None:
    """Warn that ``old`` is deprecated in favour of ``new`` (a DeprecationWarning at the caller's
    caller: the line that used the old name); :func:`droptower.deprecation.warn_deprecated`."""
    warn_deprecated(old, new, stacklevel=4)


def lag1_correlation(residuals: list[np.ndarray], compared: list[np.ndarray] | None = None) -> float:
    """The residual's lag-1 autocorrelation: sum r_i r_(i+1) over sum r_i^2, pairs taken within
    each piece of ``residuals`` (a segment, or the whole residual vector) and, with
    ``compared`` (a boolean mask per piece), only where both samples are compared (0 for a
    zero residual)."""
    num = sq = 0.0
    for k, r in enumerate(residuals):
        r = np.asarray(r, float)
        ok = np.ones(r.shape, bool) if compared is None else np.asarray(compared[k], bool)
        r = np.where(ok, r, 0.0)
        sq += float(np.sum(r ** 2))
        num += float(np.sum((r[:-1] * r[1:])[ok[:-1] & ok[1:]]))
    return num / sq if sq > 0 else 0.0


def servo_residual(segments: list["Segment"], predictions: list[np.ndarray]) -> np.ndarray:
    """The model's torque minus the measured one over each segment's compared samples, the
    segments concatenated (N*m): the residual of servo records, wherever it is formed (the
    least squares, the candidates' costs, the ranking's likelihood)."""
    return np.concatenate([(p - s.torque_nm)[s.compared] for p, s in zip(predictions, segments)])


def metrics(segments: list["Segment"], predictions: list[np.ndarray]) -> Metrics:
    """Error of ``predictions`` (one (N_s,) array per segment) against the segments' torque."""
    sq = 0.0
    n = 0
    peak = 0.0
    residuals, masks = [], []
    for seg, pred in zip(segments, predictions):
        ok = seg.compared
        r = np.where(ok, pred - np.where(ok, seg.torque_nm, 0.0), 0.0)
        residuals.append(r)
        masks.append(ok)
        sq += float(np.sum(r ** 2))
        n += int(ok.sum())
        peak = max(peak, float(np.max(np.abs(seg.torque_nm[ok]))))
    rmse = float(np.sqrt(sq / max(n, 1)))
    return Metrics(rmse, rmse / peak if peak > 0 else float("nan"), lag1_correlation(residuals, masks), n, peak)


#: how each kind of identification reports itself: data -> (to_dict, summary), registered by the
#: report modules (:mod:`.report` for servo records, :mod:`.dropreport` for drop tests); both
#: build on :func:`result_skeleton` and :func:`report_text`, so the keys and the sections are one
FORMATS: dict[str, tuple[Callable[["Identification"], dict[str, Any]], Callable[["Identification"], str]]] = {}

#: the keys of :meth:`Identification.to_dict`, the same for servo records and drop tests (a value
#: that does not apply to one kind of data is empty: ``stages`` of drop tests, ``tests_used`` of
#: servo records). ``noise`` holds the verdict's noise floor and allowance with their unit in
#: their names (``noise_floor_nm``, ``noise_floor_rad``); ``fit_error`` / ``holdout_error`` the
#: errors of the data (both with ``nrmse``, the fit's normalised RMS error, a fraction);
#: ``uncertainty`` the parameters' budget where the command line computes one (else None).
RESULT_KEYS = ("family", "data", "units", "converged", "message", "verdict", "reasons", "error_over_noise",
               "noise_ratio_limit", "noise", "n_parameters", "parameters", "derived", "at_bounds", "non_identifiable",
               "fit_error", "holdout_error", "evaluations", "nfev", "wall_s", "search", "stages", "tests_used",
               "tests_held_out", "tests_excluded", "coupling_note", "coupling_file", "uncertainty", "details")

#: the section headers of :meth:`Identification.summary`, in order, for both kinds of data (as
#: lmfit's ``fit_report``: a header per section, indented lines under it)
SUMMARY_SECTIONS = ("[[Identification]]", "[[Errors]]", "[[Parameters]]", "[[Search]]", "[[Effort]]", "[[Details]]")


def register_format(data: str, to_dict: Callable[["Identification"], dict[str, Any]],
                    summary: Callable[["Identification"], str]) -> None:
    """Register how identifications from ``data`` (:data:`SERVO`, :data:`DROPS`) convert to a
    dict and a text report."""
    FORMATS[data] = (to_dict, summary)


def result_skeleton(ident: "Identification") -> dict[str, Any]:
    """Every key of :data:`RESULT_KEYS` with what the result holds whatever its data (not yet
    JSON-safe); the report modules fill in the errors, stages and details of their data."""
    v = ident.verdict.to_dict() if ident.verdict is not None else {}
    noise = {k: val for k, val in v.items() if k.startswith(("noise_floor_", "noise_allowance_"))}
    params = ident.params.to_dict()
    for name, entry in params.items():
        entry["at_bound"] = name in ident.at_bounds
    return {
        "family": ident.family, "data": ident.data,
        "units": getattr(ident.coupling, "units", "torsional") or "torsional",
        "converged": ident.converged, "message": ident.message,
        "verdict": v.get("verdict"), "reasons": v.get("reasons", []), "error_over_noise": v.get("error_over_noise"),
        "noise_ratio_limit": v.get("noise_ratio_limit"), "noise": noise,
        "n_parameters": ident.n_parameters, "parameters": params, "derived": ident.derived,
        "at_bounds": list(ident.at_bounds), "non_identifiable": ident.non_identifiable,
        "fit_error": None, "holdout_error": None,
        "evaluations": ident.evaluations, "nfev": ident.nfev, "wall_s": ident.wall_s,
        "search": ident.search, "stages": [], "tests_used": ident.tests_used, "tests_held_out": ident.tests_held_out,
        "tests_excluded": ident.tests_excluded, "coupling_note": ident.coupling_note,
        "coupling_file": ident.coupling_file, "uncertainty": None, "details": {k: val for k, val in ident.extra.items() if k != "global_search"},
    }


def report_text(ident: "Identification", data_line: str, error_lines: list[str], details: list[str],
                name_of: Callable[[str], str] = str) -> str:
    """The text report of :meth:`Identification.summary`, the sections of
    :data:`SUMMARY_SECTIONS`: what was identified from what and the verdict, the fit's and the
    hold-out's error (``error_lines``, the data's own wording), the parameters (value, stderr,
    min, max, at-bound and held marks; the derived quantities), the search, the effort, and the
    data's ``details``. ``name_of`` names a parameter for the data's units."""
    rows = [(name_of(n), p.value, p.stderr, p.min, p.max,
             "at bound" if n in ident.at_bounds else ("held" if not p.vary else ""),
             p.unit if name_of(n) == n else unit_of(name_of(n)))
            for n, p in ident.params.items()]
    width = max([len(r[0]) for r in rows] + [len(name_of(n)) for n in ident.derived] + [4])
    lines = [SUMMARY_SECTIONS[0],
             f"    family      = {ident.family}",
             f"    data        = {data_line}",
             f"    converged   = {'yes' if ident.converged else 'NOT CONVERGED' + (': ' + ident.message if ident.message else '')}"]
    if ident.verdict is not None:
        lines += ["    " + line for line in ident.verdict.text().splitlines()]
    lines += [SUMMARY_SECTIONS[1]] + ["    " + line for line in error_lines]
    lines += [SUMMARY_SECTIONS[2],
              f"    {'name':<{width}}  {'value':>12}  {'stderr':>10}  {'min':>10}  {'max':>10}  unit"]
    for name, value, err, lo, hi, mark, unit in rows:
        lines.append(f"    {name:<{width}}  {value:>12.6g}  {err:>10.3g}  {lo:>10.3g}  {hi:>10.3g}  {unit}"
                     + (f"  ({mark})" if mark else ""))
    for name, value in ident.derived.items():
        lines.append(f"    {name_of(name):<{width}}  {float(value):>12.6g}  (derived)")
    for combo in ident.non_identifiable:
        lines.append("    not identifiable (the fit is flat along): "
                     + " ".join(f"{w:+.3g}*z({name_of(n)})" for n, w in combo.items()) + "  (z: ln value or value/scale)")
    search = ident.search
    lines.append(SUMMARY_SECTIONS[3])
    if search:
        through = f" of {search['through']}, then this family from it" if "through" in search else ""
        lines.append(f"    global search{through}: {search.get('candidates', '?')} candidates over the bounds, least "
                     f"squares from the best {search.get('local_fits', '?')}")
    else:
        lines.append("    none")
    lines += [SUMMARY_SECTIONS[4],
              f"    evaluations = {ident.evaluations} (parameter sets simulated)",
              f"    nfev        = {ident.nfev} (optimiser steps)",
              f"    wall_s      = {ident.wall_s:.2f}"]
    lines += [SUMMARY_SECTIONS[5]] + (["    " + line for line in details] or ["    none"])
    return "\n".join(lines)


def unit_of(name: str) -> str:
    """The unit a parameter's name carries as its suffix, printed (``tau1_s`` -> ``s``,
    ``k3_gain_nm_per_rad2`` -> ``N*m/rad^2``, ``phi0_per_nm`` -> ``1/(N*m)``); "" for a
    dimensionless one (``alpha``, ``matrix_loss_factor``)."""
    from droptower.units import PRINTED_UNITS

    def is_unit(token: str) -> bool:
        base = token.rstrip("0123456789")
        return base in PRINTED_UNITS and base != ""

    tokens = name.split("_")
    i = len(tokens)
    while i > 1 and (is_unit(tokens[i - 1]) or tokens[i - 1] == "per"):
        i -= 1
    unit = tokens[i:]
    while unit and unit[-1] == "per":  # a name ending in "per" carries no unit
        unit.pop()
    if not unit:
        return ""

    def printed(part: list[str]) -> str:
        out = []
        for t in part:
            base, power = t.rstrip("0123456789"), t[len(t.rstrip("0123456789")):]
            out.append(PRINTED_UNITS[base] + (f"^{power}" if power else ""))
        return "*".join(out)

    if unit[0] == "per":
        den = printed([t for t in unit[1:] if t != "per"])
        return f"1/({den})" if "*" in den else f"1/{den}"
    num = unit[:unit.index("per")] if "per" in unit else unit
    den = unit[len(num) + 1:]
    return printed(num) + (f"/{printed(den)}" if den else "")


@dataclass
class Parameter:
    """One model parameter, as lmfit's ``Parameter``: name (with its unit as suffix), value,
    standard error ``stderr`` (NaN: not estimated, e.g. held fixed), bounds ``min`` / ``max``,
    ``vary`` (False: held at ``value``) and the printed ``unit`` (default: from the name).

    Examples
    --------
    >>> Parameter("tau1_s", 0.02, min=1e-4, max=1.0)
    Parameter(name='tau1_s', value=0.02, stderr=nan, min=0.0001, max=1.0, vary=True, unit='s')
    """

    name: str
    value: float = math.nan
    stderr: float = math.nan
    min: float = -math.inf
    max: float = math.inf
    vary: bool = True
    unit: str | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise TypeError(f"a parameter's name is a non-empty str, got {self.name!r}")
        if self.unit is None:
            self.unit = unit_of(self.name)
        self.value, self.stderr = float(self.value), float(self.stderr)
        self.min, self.max = float(self.min), float(self.max)
        if not self.min <= self.max:
            raise DroptowerError(f"parameter {self.name}: min {self.min:g} is above max {self.max:g}")


class Parameters(dict):
    """Ordered name -> :class:`Parameter` (as lmfit's ``Parameters``), with a table view.

    Examples
    --------
    >>> p = Parameters()
    >>> p.add("k1_nm_per_rad", 2.0e4, vary=False)
    >>> p.add("tau1_s", 0.02, min=1e-4, max=1.0)
    >>> p.valuesdict()
    {'k1_nm_per_rad': 20000.0, 'tau1_s': 0.02}
    """

    def add(self, name: str, value: float = math.nan, *, stderr: float = math.nan, min: float = -math.inf,
            max: float = math.inf, vary: bool = True, unit: str | None = None) -> None:
        """Add (or replace) the parameter ``name``."""
        self[name] = Parameter(name, value, stderr, min, max, vary, unit)

    @classmethod
    def of(cls, values: Mapping[str, float] | Iterable[Parameter]) -> "Parameters":
        """From parameters, or from name -> value (every one held fixed: ``vary=False``)."""
        out = cls()
        if isinstance(values, Mapping):
            for name, value in values.items():
                out[name] = value if isinstance(value, Parameter) else Parameter(name, value, vary=False)
        else:
            for p in values:
                if not isinstance(p, Parameter):
                    raise DroptowerError(f"parameters: expected Parameter objects, got {type(p).__name__}")
                out[p.name] = p
        return out

    @classmethod
    def estimates(cls, values: Mapping[str, float], stderr: Mapping[str, float] | None = None) -> "Parameters":
        """Fitted values without bounds: name -> value, and name -> standard error."""
        return cls.of(Parameter(n, v, (stderr or {}).get(n, math.nan)) for n, v in values.items())

    def valuesdict(self) -> dict[str, float]:
        """name -> value."""
        return {n: p.value for n, p in self.items()}

    def vector(self) -> np.ndarray:
        """The values in order (a float array)."""
        return np.array([p.value for p in self.values()], float)

    def stderr_vector(self) -> np.ndarray:
        """The standard errors in order (NaN: not estimated)."""
        return np.array([p.stderr for p in self.values()], float)

    def to_dict(self) -> dict[str, dict[str, Any]]:
        """name -> {value, stderr, min, max, vary, unit} (JSON-ready: non-finite numbers as None)."""
        return {n: {k: (None if isinstance(v, float) and not math.isfinite(v) else v)
                    for k, v in asdict(p).items() if k != "name"} for n, p in self.items()}

    def to_frame(self) -> "pd.DataFrame":
        """One row per parameter: name, value, stderr, min, max, vary, unit."""
        import pandas as pd

        return pd.DataFrame([asdict(p) for p in self.values()],
                            columns=["name", "value", "stderr", "min", "max", "vary", "unit"])

    def pretty(self) -> str:
        """A fixed-width table, one line per parameter."""
        width = max([len(n) for n in self] + [4])
        lines = [f"{'name':<{width}}  {'value':>12}  {'stderr':>10}  {'min':>10}  {'max':>10}  vary   unit"]
        for n, p in self.items():
            lines.append(f"{n:<{width}}  {p.value:>12.6g}  {p.stderr:>10.3g}  {p.min:>10.3g}  {p.max:>10.3g}  "
                         f"{str(p.vary):<5}  {p.unit}")
        return "\n".join(lines)

    def __repr__(self) -> str:
        return f"Parameters({len(self)})\n{self.pretty()}" if self else "Parameters()"

    def _repr_html_(self) -> str:
        return self.to_frame().to_html(index=False)


def fitted_parameters(specs: list[Any], values: np.ndarray, stderr: np.ndarray | None = None,
                      vary: np.ndarray | None = None) -> Parameters:
    """:class:`Parameters` of a fit: the optimiser's parameter specs
    (:class:`~droptower.identify.fit.FitVariable`: name, lower, upper), the values, their
    standard errors (NaN where not estimated) and which were fitted (default: all)."""
    n = len(specs)
    stderr = np.full(n, np.nan) if stderr is None else np.asarray(stderr, float)
    vary = np.ones(n, bool) if vary is None else np.asarray(vary, bool)
    return Parameters.of(Parameter(s.name, float(v), float(e), float(s.lower), float(s.upper), bool(f))
                         for s, v, e, f in zip(specs, values, stderr, vary))


def split_given(init: Any, bounds: Mapping[str, tuple[float, float]] | None
                ) -> tuple[dict[str, float] | None, dict[str, tuple[float, float]] | None, dict[str, float]]:
    """What an identification is given, as (held values, bounds, first guesses): ``init`` is
    name -> held value, or :class:`Parameters` (``vary=False``: held at its value; finite
    ``min`` / ``max``: the bounds; the value of a varying one: a first guess)."""
    if not _is_parameters(init):
        return init, bounds, {}
    params = Parameters.of(init)
    held = {n: p.value for n, p in params.items() if not p.vary}
    for n, v in held.items():
        if not math.isfinite(v):
            raise DroptowerError(f"parameter {n} is held (vary=False) but has no finite value")
    given_bounds = dict(bounds or {})
    for n, p in params.items():
        if p.vary and (math.isfinite(p.min) or math.isfinite(p.max)):
            if not (math.isfinite(p.min) and math.isfinite(p.max)):
                raise DroptowerError(f"parameter {n}: give both min and max (or neither), got [{p.min:g}, {p.max:g}]")
            given_bounds.setdefault(n, (p.min, p.max))
    guesses = {n: p.value for n, p in params.items() if p.vary and math.isfinite(p.value)}
    return held or None, given_bounds or None, guesses


def servo_given(init: Any, bounds: Mapping[str, tuple[float, float]] | None
                ) -> tuple[dict[str, float] | None, dict[str, tuple[float, float]] | None]:
    """What a servo identification is given, as (initial values, bounds): ``init`` is name ->
    initial value, or :class:`Parameters` (a finite value: the initial value; finite ``min`` /
    ``max``: the bounds). The servo strategies fit every parameter, so ``vary=False`` is an error."""
    if not _is_parameters(init):
        return init, bounds
    held = [n for n, p in Parameters.of(init).items() if not p.vary]
    if held:
        raise DroptowerError(f"parameter {', '.join(held)}: an identification from servo records fits every "
                             "parameter of its family (none is held); give the value as an initial value (vary left True)")
    _, given_bounds, guesses = split_given(init, bounds)
    return guesses or None, given_bounds


def _is_parameters(init: Any) -> bool:
    return isinstance(init, Parameters) or (isinstance(init, (list, tuple)) and bool(init)
                                            and all(isinstance(p, Parameter) for p in init))


def place_guesses(kind: str, names: list[str], x0: np.ndarray, guesses: Mapping[str, float]) -> None:
    """Write the first guesses ``guesses`` (name -> value) into the start vector ``x0`` in place."""
    for name, value in guesses.items():
        if name not in names:
            raise DroptowerError(f"family {kind} has no parameter {name} (its parameters: {', '.join(names)})")
        x0[names.index(name)] = value


#: the old constructor arguments and attributes of :class:`Identification` -> their names now
#: (accepted for one release with a DeprecationWarning)
RENAMED_ARGUMENTS = {"fit": "fit_error", "holdout": "holdout_error", "time_s": "wall_s", "_converged": "converged",
                     "_evaluations": "evaluations", "_nfev": "nfev"}


class Identification:
    """The result of identifying one model family, from servo records or from drop tests: one
    type, one schema (:meth:`to_dict`), one text report (:meth:`summary`) for both.

    The constructor takes each attribute below by its name (the first six also by position).

    Attributes
    ----------
    family : str
        The family's name (``zerodim6``, ``template``, ...).
    params : Parameters
        The identified parameters: value, standard error ``stderr``, bounds, ``vary`` (False:
        held at a given value), unit.
    at_bounds : list of str
        Fitted parameters that ended on a bound.
    fit_error, holdout_error
        The error on the fitting and on the held-out data: servo records,
        :class:`Metrics` (torque RMSE, ``nrmse``); drop tests, a dict (``angle_nrmse``,
        ``torque_nrmse``, ``tests``, ``per_test``). ``holdout_error`` is None without held-out
        data. :attr:`nrmse` is the fit's normalised error of either.
    coupling : Coupling
        The single coupling that stands for the fit (the one written out).
    data : str
        :data:`SERVO` or :data:`DROPS`: what it was identified from.
    stages : list of FitResult
        Servo records: one :class:`~droptower.identify.fit.FitResult` per stage.
    predict : callable or None
        Servo records: the model's torque on other segments.
    derived : dict
        Quantities computed from the parameters (e.g. dashpot coefficients).
    coupling_note : str
        What the coupling represents where the parameters depend on amplitude or frequency.
    extra : dict
        The family's report (its analytic start, its stages' notes, ...).
    wall_s : float
        Wall time of the identification (s).
    verdict : Verdict or None
        The fit against the data's noise floor (:mod:`droptower.identify.verdict`).
    family_model
        The family bound to the data's scale (its parameter specs, couplings and derived
        quantities), where known.
    message : str
        The optimiser's last word (drop tests).
    non_identifiable : list of dict
        Directions along which the fit is flat (parameter name -> weight).
    tests_used, tests_held_out, tests_excluded
        Drop tests: the fitting tests, the held-out tests, the excluded ones with the reason.
    search : dict
        The global search's summary (candidates, local fits, ...), empty where none ran.
    coupling_file : str or None
        Where :meth:`write_coupling` wrote the coupling.
    angle_rss_rad2, angle_samples
        Drop tests: the angle residual's sum of squares (rad^2) and its sample count.
    converged : bool or None
        Given: whether the fit converged; None: every stage in :attr:`stages` did.
    evaluations, nfev : int or None
        Given: the parameter sets simulated and the optimiser's steps; None: the stages' sums.

    The names of release 0.1 (``fit``, ``holdout``, ``time_s``, ``std_error``, ``_converged``,
    ``_evaluations``, ``_nfev``) still work for this release with a DeprecationWarning.
    """

    def __init__(self, family: str, params: Parameters, at_bounds: list[str], fit_error: Any = None,
                 coupling: "Coupling" = None, data: str = SERVO, *, stages: list[Any] | None = None,
                 predict: Callable[[list], list[np.ndarray]] | None = None, derived: dict[str, float] | None = None,
                 coupling_note: str = "", extra: dict | None = None, holdout_error: Any = None, wall_s: float = 0.0,
                 verdict: Any = None, family_model: Any = None, message: str = "",
                 non_identifiable: list[dict[str, float]] | None = None, tests_used: list[str] | None = None,
                 tests_held_out: list[str] | None = None, tests_excluded: list[dict[str, str]] | None = None,
                 search: dict[str, Any] | None = None, coupling_file: str | None = None,
                 angle_rss_rad2: float = math.nan, angle_samples: int = 0, converged: bool | None = None,
                 evaluations: int | None = None, nfev: int | None = None, **old: Any) -> None:
        given = {"fit_error": fit_error, "holdout_error": holdout_error, "wall_s": wall_s, "converged": converged,
                 "evaluations": evaluations, "nfev": nfev}
        for name, value in old.items():
            if name not in RENAMED_ARGUMENTS:
                raise TypeError(f"Identification() got an unexpected keyword argument {name!r}")
            deprecated(f"Identification({name}=...)", f"Identification({RENAMED_ARGUMENTS[name]}=...)")
            given[RENAMED_ARGUMENTS[name]] = value
        self.family = family
        self.params = params
        self.at_bounds = at_bounds
        self.fit_error = given["fit_error"]
        self.coupling = coupling
        self.data = data
        self.stages = list(stages or [])
        self.predict = predict
        self.derived = dict(derived or {})
        self.coupling_note = coupling_note
        self.extra = dict(extra or {})
        self.holdout_error = given["holdout_error"]
        self.wall_s = float(given["wall_s"])
        self.verdict = verdict
        self.family_model = family_model
        self.message = message
        self.non_identifiable = list(non_identifiable or [])
        self.tests_used = list(tests_used or [])
        self.tests_held_out = list(tests_held_out or [])
        self.tests_excluded = list(tests_excluded or [])
        self._search = dict(search or {})
        self.coupling_file = coupling_file
        self.angle_rss_rad2 = angle_rss_rad2
        self.angle_samples = angle_samples
        self._converged = given["converged"]
        self._evaluations = given["evaluations"]
        self._nfev = given["nfev"]

    # ------------------------------------------------------------------ views
    @property
    def converged(self) -> bool:
        """Every least-squares stage converged (drop tests: the final fit did)."""
        return bool(self._converged) if self._converged is not None else all(s.converged for s in self.stages)

    @converged.setter
    def converged(self, value: bool | None) -> None:
        self._converged = value

    @property
    def n_parameters(self) -> int:
        """The number of parameters (fitted and held)."""
        return len(self.params)

    @property
    def parameters(self) -> dict[str, float]:
        """name -> value (a view of :attr:`params`)."""
        return self.params.valuesdict()

    @property
    def stderr(self) -> dict[str, float]:
        """name -> standard error (NaN: not estimated), as each :attr:`Parameter.stderr`;
        assigning a dict sets the parameters'."""
        return {n: p.stderr for n, p in self.params.items()}

    @stderr.setter
    def stderr(self, values: Mapping[str, float]) -> None:
        for n, v in values.items():
            self.params[n].stderr = float(v)

    @property
    def search(self) -> dict[str, Any]:
        """The global search's summary (candidates over the bounds, local fits, ...); empty where
        none ran. Servo records keep it in their family's report (``extra``): one name here."""
        return self._search or dict(self.extra.get("global_search", {}))

    @search.setter
    def search(self, value: Mapping[str, Any]) -> None:
        self._search = dict(value or {})

    @property
    def evaluations(self) -> int:
        """Parameter sets simulated over the data (a Jacobian of n columns counts n)."""
        if self._evaluations is not None:
            return self._evaluations
        # the start another family's identification gave, where it ran for this one (zerodim20's zerodim6)
        start = int(self.extra.get("start", {}).get("evaluations", 0))
        return sum(s.evaluations for s in self.stages) + int(self.extra.get("search_evaluations", 0)) + start

    @evaluations.setter
    def evaluations(self, value: int | None) -> None:
        self._evaluations = value

    @property
    def nfev(self) -> int:
        """Optimiser steps."""
        return self._nfev if self._nfev is not None else sum(s.nfev for s in self.stages)

    @nfev.setter
    def nfev(self, value: int | None) -> None:
        self._nfev = value

    @property
    def nrmse(self) -> float:
        """The fit's normalised RMS error (a fraction): of the torque (servo records) or of the
        angle (drop tests)."""
        return float(self.fit_error["angle_nrmse"]) if self.data == DROPS else float(self.fit_error.nrmse)

    @property
    def holdout_nrmse(self) -> float:
        """The held-out data's normalised RMS error (a fraction; NaN without held-out data)."""
        h = self.holdout_error
        if not h:
            return math.nan
        return float(h["angle_nrmse"]) if self.data == DROPS else float(h.nrmse)

    # ------------------------------------------------------------------ the names of release 0.1
    fit = renamed_attribute("Identification", "fit", "fit_error")
    holdout = renamed_attribute("Identification", "holdout", "holdout_error")
    time_s = renamed_attribute("Identification", "time_s", "wall_s")
    std_error = renamed_attribute("Identification", "std_error", "stderr")

    # ------------------------------------------------------------------ actions
    def evaluate_holdout(self, segments: list) -> Metrics:
        """The error on held-out servo records (stored as :attr:`holdout_error`)."""
        if self.predict is None:
            raise DroptowerError(f"family {self.family}: this identification cannot predict servo records")
        self.holdout_error = metrics(segments, self.predict(segments))
        return self.holdout_error

    def write_coupling(self, path: str | Path, sources: list[str] | None = None) -> Path:
        """Write the fitted coupling as TOML, its description naming the fit's quality (and its
        source the data ``sources``), read it back to check it; recorded in :attr:`coupling_file`."""
        from droptower.errors import make_folder
        from droptower.rheology import coupling_to_toml, load_coupling

        c = copy.copy(self.coupling)
        if self.data == DROPS:
            quality = f"angle nRMSE {100 * self.fit_error['angle_nrmse']:.2f} % on {len(self.tests_used)} drop tests"
            if self.holdout_error:
                quality += f", {100 * self.holdout_error['angle_nrmse']:.2f} % on {self.holdout_error['tests']} held out"
            c.description = f"{c.description}. Identified by droptower from drop tests as {self.family} ({quality})."
        else:
            quality = f"nRMSE {100 * self.fit_error.nrmse:.2f} % on the fitting data"
            if self.holdout_error:
                quality += f", {100 * self.holdout_error.nrmse:.2f} % on hold-out data"
            c.description = (f"{c.description}. Identified by droptower from servo records as {self.family} ({quality}). "
                             f"{self.coupling_note}").strip()
        if sources:
            c.source = f"{c.source}; identified from {', '.join(sources)}"
        path = Path(path)
        make_folder(path.parent)
        path.write_text(coupling_to_toml(c))
        load_coupling(path)  # what is written must read back
        self.coupling_file = str(path)
        return path

    # ------------------------------------------------------------------ conversions
    def to_dict(self) -> dict[str, Any]:
        """Everything it reports, JSON-ready, with the same keys for servo records and drop tests
        (:data:`RESULT_KEYS`; also what the ``identify`` command prints as JSON)."""
        doc = FORMATS[self.data][0](self)
        if list(doc) != list(RESULT_KEYS):  # one schema: a format that adds or drops a key is a bug here
            raise RuntimeError(f"the {self.data} report's keys differ from RESULT_KEYS: {sorted(set(doc) ^ set(RESULT_KEYS))}")
        return doc

    def to_frame(self) -> "pd.DataFrame":
        """The parameters as a table (:meth:`Parameters.to_frame`) with an ``at_bound`` column."""
        table = self.params.to_frame()
        table["at_bound"] = table["name"].isin(self.at_bounds)
        return table

    def summary(self) -> str:
        """The text report, the same sections for servo records and drop tests
        (:data:`SUMMARY_SECTIONS`; what ``droptower identify`` prints)."""
        return FORMATS[self.data][1](self)

    def __repr__(self) -> str:
        verdict = f", {self.verdict.verdict}" if self.verdict is not None else ""
        state = "converged" if self.converged else "NOT converged"
        return (f"<Identification {self.family} from {self.data}: {self.n_parameters} parameters, {state}, "
                f"nRMSE {100 * self.nrmse:.3g} %{verdict}>\n{self.params.pretty()}")

    def _repr_html_(self) -> str:
        head = repr(self).splitlines()[0].strip("<>")
        return f"<p>{head}</p>" + self.to_frame().to_html(index=False)
