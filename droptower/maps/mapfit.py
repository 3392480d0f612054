"""A fitted characteristic map: coefficients of Rapp et al. 2022, eq. 19 and eq. 20 (or of another
:class:`~droptower.maps.forms.MapForm`), how well they fit and cross-validate, where they were
measured, and the ``map.json`` file that carries them.

``map.json`` keys (every value's unit is in its name; relative errors in percent):

- ``format`` ("droptower-map"), ``format_version`` (1), ``equations`` (the two equations, text),
  ``form`` (``name``, ``stiffness_terms``, ``ratio_terms``: the term kinds of
  :mod:`droptower.maps.forms`; absent means the paper's form). The coefficient names and units
  below are the paper form's; another form numbers its own terms the same way (``k1`` …).
- ``coefficients``: ``k1_nm_per_deg``, ``k2_per_deg``, ``k3_nm_per_deg``, ``k4_per_deg``,
  ``k5_nm_per_deg_per_sqrt_hz``, ``k6_nm_per_deg``, ``k7_per_hz`` (eq. 19: stiffness in N·m/deg,
  amplitude in deg, frequency in Hz) and ``k8_nm_per_deg``, ``k9_per_deg``, ``k10_nm_per_deg``,
  ``k11_per_deg``, ``k12_nm_per_deg``, ``k13_per_deg`` (eq. 20: stiffness / damping ratio).
- ``coefficients_std``: the same keys, standard uncertainties from the fit's Jacobian
  (``null``: not identifiable from these tests). Eq. 20's are conditional on eq. 19.
- ``at_bounds``: coefficient names (``k9``) that sit on their bound (zero).
- ``not_unique``: coefficient names that another multi-start solution inside the approximate
  95 % confidence region puts more than 2 uncertainties away: the tests do not pin them down
  (the map's predictions in the measured range are still fine; the coefficient is not physics).
- ``fit``: ``n_tests``, ``stiffness_rms_error_pct``, ``stiffness_max_error_pct``,
  ``damping_ratio_rms_error_pct``, ``damping_ratio_max_error_pct`` (model vs. test, relative),
  ``stiffness_condition_number``, ``damping_condition_number`` (of the column-scaled Jacobian),
  ``stiffness_cv_rms_error_pct``, ``damping_ratio_cv_rms_error_pct`` (each test predicted by the
  map fitted without its group, see ``cross_validation``: the error to expect between tests).
- ``cross_validation``: how the tests were grouped (``leave-one-drop-height-out (15 folds)``).
- ``range``: ``amplitude_deg_min``, ``amplitude_deg_max``, ``frequency_hz_min``,
  ``frequency_hz_max``: the rectangle of the tests' extremes; ``hull_amplitude_deg_frequency_hz``:
  the vertices of the convex hull of the tested points in (log amplitude, frequency), where the
  map interpolates (outside it, it extrapolates).
- ``excluded``: ``[{"test": file or "row N", "reason": ...}]``; ``source``: the results file.
- ``fixtures``: the lever fixtures of the tests used (a lab's names, else "J kg*m^2");
  ``temperature_range_c``: [min, max] of their temperatures in degC (null without);
  ``coverage``: one line per fixture or condition left out entirely, with why, and a
  temperature span over 5 K (:mod:`droptower.maps.coverage`). Absent in older files.
- ``input_uncertainty``: the rig's input uncertainties the map's expanded uncertainties were
  computed with (:class:`~droptower.rig.uncertainty.RigUncertainty`'s fields; absent: none given);
  ``validate`` reuses them where it is given none. Absent in older files.
"""
from __future__ import annotations

import json
import math
import os
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Optional

import numpy as np
from numpy.typing import ArrayLike
from pydantic import create_model

from droptower import sdof
from droptower.errors import DroptowerError, WriteError, readable_file, unreadable_file
from droptower.jsonsafe import json_safe
from droptower.maps.forms import PAPER, UNIT_TEXT, Equation, MapForm
from droptower.maps.results import ExcludedTest
from droptower.config_validation import StrictModel, validate

if TYPE_CHECKING:
    import pandas as pd

FORMAT = "droptower-map"
FORMAT_VERSION = 1
#: coefficient name -> unit suffix, eq. 19 then eq. 20
UNITS: dict[str, str] = PAPER.units


@dataclass(frozen=True)
class FitStats:
    """How well the map fits the tests it came from (relative errors in percent)."""

    n_tests: int
    stiffness_rms_error_pct: float
    stiffness_max_error_pct: float
    damping_ratio_rms_error_pct: float
    damping_ratio_max_error_pct: float
    stiffness_condition_number: float
    damping_condition_number: float
    stiffness_cv_rms_error_pct: float | None = None
    damping_ratio_cv_rms_error_pct: float | None = None


@dataclass(frozen=True)
class MapRange:
    """The measured amplitude (deg) and frequency (Hz) range of the tests: the rectangle of
    their extremes and ``hull``, the vertices (amplitude_deg, frequency_hz) of the convex hull
    of the tested points in (log amplitude, frequency) (empty: unknown, e.g. an older file)."""

    amplitude_deg_min: float
    amplitude_deg_max: float
    frequency_hz_min: float
    frequency_hz_max: float
    hull: tuple[tuple[float, float], ...] = ()

    @classmethod
    def of_points(cls, amplitude_deg: ArrayLike, frequency_hz: ArrayLike) -> "MapRange":
        """The range of tested points: the rectangle and the hull (in log10 amplitude, since
        drop heights spread the amplitudes over decades)."""
        a, f = np.asarray(amplitude_deg, float), np.asarray(frequency_hz, float)
        hull: tuple[tuple[float, float], ...] = ()
        pts = np.column_stack([np.log10(a), f])
        if len(np.unique(pts, axis=0)) >= 3:
            from scipy.spatial import ConvexHull, QhullError
            try:
                hull = tuple((float(10 ** x), float(y)) for x, y in pts[ConvexHull(pts).vertices])
            except QhullError:  # the points lie on a line: no area, only the rectangle
                hull = ()
        return cls(float(a.min()), float(a.max()), float(f.min()), float(f.max()), hull)

    def in_rectangle(self, amplitude_deg: ArrayLike, frequency_hz: ArrayLike) -> np.ndarray:
        """Inside the rectangle of the tests' extremes (bounds included), as the paper states
        its range ("~20-60 Hz and ~0.15-3.2 deg")."""
        a, f = np.broadcast_arrays(np.asarray(amplitude_deg, float), np.asarray(frequency_hz, float))
        return ((a >= self.amplitude_deg_min) & (a <= self.amplitude_deg_max)
                & (f >= self.frequency_hz_min) & (f <= self.frequency_hz_max))

    def in_hull(self, amplitude_deg: ArrayLike, frequency_hz: ArrayLike) -> np.ndarray:
        """Inside the convex hull of the tested points (bounds included, 1e-9 relative slack);
        the rectangle where the hull is unknown. A drop tower's tests lie on one curve per
        inertia (larger drops: larger amplitude, lower frequency), so the rectangle's corners
        hold no test: only the hull is where the map interpolates."""
        if not self.hull:
            return self.in_rectangle(amplitude_deg, frequency_hz)
        a, f = np.broadcast_arrays(np.asarray(amplitude_deg, float), np.asarray(frequency_hz, float))
        verts = np.array([(np.log10(x), y) for x, y in self.hull])
        q = np.column_stack([np.log10(np.where(a > 0, a, np.nan)).ravel(), f.ravel()])
        # counter-clockwise vertices (ConvexHull's order in 2-D): inside = left of every edge
        edges = np.roll(verts, -1, axis=0) - verts
        rel = q[:, None, :] - verts[None, :, :]
        cross = edges[None, :, 0] * rel[:, :, 1] - edges[None, :, 1] * rel[:, :, 0]
        scale = np.linalg.norm(edges, axis=1)[None, :] * (1 + np.abs(verts).max())
        inside = np.all(cross >= -1e-9 * scale, axis=1) & np.all(np.isfinite(q), axis=1)
        return inside.reshape(a.shape)


@dataclass
class MapFit:
    """The characteristic map of Rapp et al. 2022 (eq. 19 and eq. 20, or another ``form``) fitted to drop tests.

    coefficients / uncertainties: ``"k1"`` … ``"k13"`` in the paper's units (:data:`UNITS`;
    another form: ``form.units``);
    an uncertainty is ``inf`` where the tests do not identify the coefficient. at_bounds: names
    of coefficients on their bound (zero); not_unique: names of coefficients that another
    equally consistent solution places elsewhere (see the module docstring). fixtures: the lever
    fixtures of the tests used (a lab's names, else the inertias in kg*m^2); temperature_range_c:
    (min, max) temperature of the tests used (degC), None where the results have none; coverage:
    what the map does not cover (:func:`~droptower.maps.coverage.coverage_notes`). Predictions take amplitude in deg and frequency in Hz
    (arrays broadcast) and return N·m/deg and the damping ratio (-).
    """

    coefficients: dict[str, float]
    uncertainties: dict[str, float]
    stats: FitStats
    range: MapRange
    excluded: list[ExcludedTest] = field(default_factory=list)
    at_bounds: tuple[str, ...] = ()
    not_unique: tuple[str, ...] = ()
    source: str | None = None
    form: MapForm = PAPER
    cross_validation: str | None = None
    fixtures: tuple[str, ...] = ()
    temperature_range_c: tuple[float, float] | None = None
    coverage: tuple[str, ...] = ()
    input_uncertainty: dict[str, Any] | None = None

    @property
    def stiffness_params(self) -> np.ndarray:
        """The stiffness equation's coefficients (k1..k7 of eq. 19)."""
        return np.array([self.coefficients[k] for k in self.form.stiffness_names])

    @property
    def ratio_params(self) -> np.ndarray:
        """The c/d equation's coefficients (k8..k13 of eq. 20)."""
        return np.array([self.coefficients[k] for k in self.form.ratio_names])

    def stiffness_nm_per_deg(self, amplitude_deg: ArrayLike, frequency_hz: ArrayLike) -> np.ndarray:
        """Dynamic stiffness (N·m/deg) from eq. 19 (or the form's stiffness equation)."""
        return self.form.stiffness.value(self.stiffness_params, amplitude_deg, frequency_hz)

    def damping_ratio(self, amplitude_deg: ArrayLike, frequency_hz: ArrayLike) -> np.ndarray:
        """Damping ratio d = E_diss/E_el (-, Rapp et al. 2022, eq. 16): stiffness over c/d (eq. 19 / eq. 20)."""
        return self.stiffness_nm_per_deg(amplitude_deg, frequency_hz) / self.form.ratio.value(
            self.ratio_params, amplitude_deg, frequency_hz)

    def lehr_damping(self, amplitude_deg: ArrayLike, frequency_hz: ArrayLike) -> np.ndarray:
        """Lehr's D (ζ, -) of the map's decay at (amplitude, frequency): from :meth:`damping_ratio`
        through r = δ/ω (docs/theory.md#damping-measures)."""
        return sdof.damping_measures(self.damping_ratio(amplitude_deg, frequency_hz))[0]

    def loss_factor(self, amplitude_deg: ArrayLike, frequency_hz: ArrayLike) -> np.ndarray:
        """Loss factor η (-) of the linear Kelvin–Voigt coupling with the map's decay at (amplitude,
        frequency) (docs/theory.md#damping-measures)."""
        return sdof.damping_measures(self.damping_ratio(amplitude_deg, frequency_hz))[1]

    def in_range(self, amplitude_deg: ArrayLike, frequency_hz: ArrayLike) -> np.ndarray:
        """True where (amplitude, frequency) lies inside the measured range: the convex hull of
        the tested points (:meth:`MapRange.in_hull`; the rectangle for a map without one)."""
        return self.range.in_hull(amplitude_deg, frequency_hz)

    def in_rectangle(self, amplitude_deg: ArrayLike, frequency_hz: ArrayLike) -> np.ndarray:
        """True inside the rectangle of the tests' extremes, the paper's statement of the range
        ("~20-60 Hz and ~0.15-3.2 deg", Rapp et al. 2022, validation section)."""
        return self.range.in_rectangle(amplitude_deg, frequency_hz)

    # ---- map.json ----------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """The ``map.json`` content (keys in the module docstring); non-finite numbers are null."""
        units = self.form.units
        return {
            "format": FORMAT,
            "format_version": FORMAT_VERSION,
            "equations": self.form.equations(),
            "form": self.form.to_dict(),
            "coefficients": {f"{k}_{u}": json_safe(self.coefficients[k]) for k, u in units.items()},
            "coefficients_std": {f"{k}_{u}": json_safe(self.uncertainties[k]) for k, u in units.items()},
            "at_bounds": list(self.at_bounds),
            "not_unique": list(self.not_unique),
            "fit": json_safe(asdict(self.stats)),
            "cross_validation": self.cross_validation,
            "range": {**{k: v for k, v in asdict(self.range).items() if k != "hull"},
                      "hull_amplitude_deg_frequency_hz": [list(v) for v in self.range.hull]},
            "excluded": [asdict(e) for e in self.excluded],
            "source": self.source,
            "fixtures": list(self.fixtures),
            "temperature_range_c": list(self.temperature_range_c) if self.temperature_range_c else None,
            "coverage": list(self.coverage),
            **({"input_uncertainty": json_safe(self.input_uncertainty)} if self.input_uncertainty else {}),
        }

    def coefficient_table(self) -> "pd.DataFrame":
        """The coefficients as a table (written as ``map.csv|.parquet|.xlsx``): ``coefficient``,
        ``equation``, ``unit``, ``value``, ``std`` (NaN: not identifiable), ``at_bound``,
        ``not_unique``. Only ``map.json`` is read back (:meth:`from_json`)."""
        import pandas as pd

        paper = self.form == PAPER
        stiffness = "Rapp et al. 2022, eq. 19" if paper else "stiffness"
        ratio = "Rapp et al. 2022, eq. 20" if paper else "stiffness over damping ratio"
        return pd.DataFrame([{
            "coefficient": k, "equation": stiffness if k in self.form.stiffness_names else ratio,
            "unit": UNIT_TEXT[u], "value": self.coefficients[k],
            "std": self.uncertainties[k] if math.isfinite(self.uncertainties[k]) else math.nan,
            "at_bound": k in self.at_bounds, "not_unique": k in self.not_unique} for k, u in self.form.units.items()])

    def to_json(self, path: str | Path | None = None) -> str:
        """The map as JSON text; with ``path``, also written there (atomically)."""
        text = json.dumps(self.to_dict(), indent=2) + "\n"
        if path is not None:
            path = Path(path)
            tmp = path.with_name(f".{path.name}.tmp")
            try:
                tmp.write_text(text)
                os.replace(tmp, path)
            except OSError as exc:
                raise WriteError.from_os_error(exc, path) from None
        return text

    @classmethod
    def from_dict(cls, data: dict[str, Any], file: str | Path | None = None) -> "MapFit":
        """Build a map from ``map.json`` content; malformed content is a one-line error."""
        doc = validate(_MapFile, data, file)
        if doc.format != FORMAT or doc.format_version != FORMAT_VERSION:
            raise DroptowerError(f"not a {FORMAT} file of version {FORMAT_VERSION}", file=file)
        try:
            form = PAPER if doc.form is None else MapForm(doc.form.name, Equation(tuple(doc.form.stiffness_terms)),
                                                         Equation(tuple(doc.form.ratio_terms)))
        except ValueError as exc:
            raise DroptowerError(f"form: {exc}", file=file) from None
        units = form.units
        for part, given in (("coefficients", doc.coefficients), ("coefficients_std", doc.coefficients_std)):
            expected = [f"{k}_{u}" for k, u in units.items()]
            for key in expected:
                if key not in given:
                    raise DroptowerError(f"field {part}: field {key}: missing field", file=file)
            for key in given:
                if key not in expected:
                    raise DroptowerError(f"field {part}: field {key}: not a coefficient of the form {form.name!r} "
                                         f"({', '.join(expected)})", file=file)
        coefficients = {k: doc.coefficients[f"{k}_{u}"] for k, u in units.items()}
        stds = {k: doc.coefficients_std[f"{k}_{u}"] for k, u in units.items()}
        cv = ("stiffness_cv_rms_error_pct", "damping_ratio_cv_rms_error_pct")
        return cls(
            coefficients=coefficients,
            uncertainties={k: math.inf if v is None else v for k, v in stds.items()},
            stats=FitStats(**{k: v if k in cv else math.inf if v is None else v for k, v in doc.fit.model_dump().items()}),
            range=MapRange(**{k: v for k, v in doc.range.model_dump().items() if k != "hull_amplitude_deg_frequency_hz"},
                           hull=tuple(tuple(v) for v in doc.range.hull_amplitude_deg_frequency_hz)),
            excluded=[ExcludedTest(**e.model_dump()) for e in doc.excluded],
            at_bounds=tuple(doc.at_bounds),
            not_unique=tuple(doc.not_unique),
            source=doc.source,
            form=form,
            cross_validation=doc.cross_validation,
            fixtures=tuple(doc.fixtures),
            temperature_range_c=tuple(doc.temperature_range_c) if doc.temperature_range_c else None,
            coverage=tuple(doc.coverage),
            input_uncertainty=_input_uncertainty(doc.input_uncertainty, file),
        )

    @classmethod
    def from_json(cls, path: str | Path) -> "MapFit":
        """Read ``map.json``; a missing, unreadable or malformed file is a one-line error."""
        path = readable_file(path)
        return cls.from_dict(read_json_object(path, "a map file"), path)

    def to_frame(self) -> "pd.DataFrame":
        """The coefficients as a table (:meth:`coefficient_table`)."""
        return self.coefficient_table()

    def __repr__(self) -> str:
        s, r = self.stats, self.range
        return (f"<MapFit {self.form.name}: {s.n_tests} tests, stiffness rms {s.stiffness_rms_error_pct:.2f} %, "
                f"damping ratio rms {s.damping_ratio_rms_error_pct:.2f} %; {r.amplitude_deg_min:.3g}-"
                f"{r.amplitude_deg_max:.3g} deg, {r.frequency_hz_min:.4g}-{r.frequency_hz_max:.4g} Hz>")

    def _repr_html_(self) -> str:
        return f"<p>{repr(self).strip('<>')}</p>" + self.coefficient_table().to_html(index=False)

    # ---- text summary ------------------------------------------------------------------
    def summary(self) -> str:
        """Human-readable summary: coefficients ± uncertainty, errors, range, exclusions."""
        s, r, form = self.stats, self.range, self.form
        paper = form == PAPER
        lines = [
            f"characteristic map ({'Rapp et al. 2022, eq. 19, eq. 20' if paper else f'form {form.name}'}) from "
            f"{self.source or 'results'}: {s.n_tests} tests used, {len(self.excluded)} excluded",
            f"measured range: amplitude {r.amplitude_deg_min:.3g}-{r.amplitude_deg_max:.3g} deg, "
            f"frequency {r.frequency_hz_min:.4g}-{r.frequency_hz_max:.4g} Hz"
            + (f"; fixtures {', '.join(self.fixtures)}" if self.fixtures else "")
            + (f"; temperature {self.temperature_range_c[0]:.1f}-{self.temperature_range_c[1]:.1f} degC"
               if self.temperature_range_c else ""),
            f"{'eq. 19  ' if paper else ''}c(a, f) = {form.stiffness.text(form.stiffness_names)}  [N*m/deg]",
            *self._coefficient_lines(form.stiffness_names),
            f"  stiffness error: rms {s.stiffness_rms_error_pct:.2f} %{_cv_text(s.stiffness_cv_rms_error_pct)}, "
            f"max {s.stiffness_max_error_pct:.2f} % (condition number {s.stiffness_condition_number:.3g})",
            f"{'eq. 20  c/d(a)' if paper else 'c/d(a, f)'} = {form.ratio.text(form.ratio_names)}  [N*m/deg]",
            *self._coefficient_lines(form.ratio_names),
            f"  damping ratio d = E_diss/E_el (Rapp et al. 2022) error: rms {s.damping_ratio_rms_error_pct:.2f} %{_cv_text(s.damping_ratio_cv_rms_error_pct)}, "
            f"max {s.damping_ratio_max_error_pct:.2f} % (condition number {s.damping_condition_number:.3g})",
        ]
        if self.cross_validation:
            lines.append(f"cross-validated: {self.cross_validation}")
        poor = [k for k in form.units if not abs(self.uncertainties[k]) <= 0.5 * abs(self.coefficients[k])]
        if poor:
            lines.append(f"poorly identified (uncertainty > 50 % of the value): {', '.join(poor)}")
        if self.not_unique:
            lines.append(f"not unique (another solution fits within the 95 % confidence region): {', '.join(self.not_unique)}")
        if self.excluded:
            lines.append("excluded tests:")
            lines += [f"  {e.test}: {e.reason}" for e in self.excluded]
        if self.coverage:
            lines.append("not covered by the map:")
            lines += [f"  {line}" for line in self.coverage]
        return "\n".join(lines)

    def _coefficient_lines(self, names: list[str]) -> list[str]:
        out = []
        units = self.form.units
        for k in names:
            u = units[k]
            std = self.uncertainties[k]
            std_text = f"{std:.3g}" if math.isfinite(std) else "not identifiable"
            bound = "  (at bound)" if k in self.at_bounds else ""
            out.append(f"  {k:>3} = {self.coefficients[k]:.5g} ± {std_text} {UNIT_TEXT[u]}{bound}")
        return out


def read_json_object(path: Path, what: str) -> dict[str, Any]:
    """The JSON object in ``path`` (a readable file); anything else is a one-line error saying it
    is not ``what``."""
    try:
        data = json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise DroptowerError(f"not valid JSON ({exc})", file=path) from None
    except RecursionError:
        raise DroptowerError(f"not {what} (nested too deeply)", file=path) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise unreadable_file(path, exc) from None
    if not isinstance(data, dict):
        raise DroptowerError(f"not {what} (expected a JSON object)", file=path)
    return data


def _cv_text(value: float | None) -> str:
    return "" if value is None else f" (cross-validated {value:.2f} %)"


# ---- map.json schema (pydantic), so a hand-edited or truncated file gives a one-line error ----
_CV_FIELDS = ("stiffness_cv_rms_error_pct", "damping_ratio_cv_rms_error_pct")  # absent in older files
_Fit = create_model("fit", __base__=StrictModel, n_tests=(int, ...),
                    **{k: (Optional[float], None if k in _CV_FIELDS else ...)
                       for k in FitStats.__dataclass_fields__ if k != "n_tests"})
_Range = create_model("range", __base__=StrictModel, hull_amplitude_deg_frequency_hz=(list[tuple[float, float]], []),
                      **{k: (float, ...) for k in MapRange.__dataclass_fields__ if k != "hull"})


class _Excluded(StrictModel):
    test: str
    reason: str


class _Form(StrictModel):
    name: str
    stiffness_terms: list[str]
    ratio_terms: list[str]


def _input_uncertainty(data: dict[str, Any] | None, file: str | Path | None) -> dict[str, Any] | None:
    """A map file's ``input_uncertainty``, checked as a rig's ``[uncertainty]`` table (None: none)."""
    if not data:
        return None
    from droptower.rig.uncertainty import RigUncertainty

    return validate(RigUncertainty, data, file).model_dump(exclude_none=True)


class _MapFile(StrictModel):
    format: str
    format_version: int
    equations: dict[str, str] = {}
    form: Optional[_Form] = None
    coefficients: dict[str, float]
    coefficients_std: dict[str, Optional[float]]
    at_bounds: list[str] = []
    not_unique: list[str] = []
    fit: _Fit  # type: ignore[valid-type]
    range: _Range  # type: ignore[valid-type]
    excluded: list[_Excluded] = []
    source: Optional[str] = None
    cross_validation: Optional[str] = None
    fixtures: list[str] = []                               # absent in older files
    temperature_range_c: Optional[tuple[float, float]] = None
    coverage: list[str] = []
    input_uncertainty: dict[str, Any] | None = None
