"""A fitted characteristic map: coefficients of seed 004 eq. 19 and eq. 20, how well they fit,
where they were measured, and the ``map.json`` file that carries them.

``map.json`` keys (every value's unit is in its name; relative errors in percent):

- ``format`` ("droptower-map"), ``format_version`` (1), ``equations`` (the two equations, text).
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
  ``stiffness_condition_number``, ``damping_condition_number`` (of the column-scaled Jacobian).
- ``range``: ``amplitude_deg_min``, ``amplitude_deg_max``, ``frequency_hz_min``,
  ``frequency_hz_max``: the measured range (the map interpolates inside, extrapolates outside).
- ``excluded``: ``[{"test": file or "row N", "reason": ...}]``; ``source``: the results file.
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

from droptower.errors import DroptowerError
from droptower.maps import model
from droptower.maps.results import ExcludedTest
from droptower.validation import StrictModel, validate

if TYPE_CHECKING:
    import pandas as pd

FORMAT = "droptower-map"
FORMAT_VERSION = 1
EQUATIONS = {
    "stiffness_nm_per_deg": "k1*10^(-k2*a) + k3*10^(-k4*a) + k5*sqrt(f) + k6*10^(-k7*f)  (seed 004 eq. 19)",
    "damping_ratio": "stiffness_nm_per_deg / (k8*10^(-k9*a) + k10*10^(-k11*a) + k12*10^(-k13*a))  (seed 004 eq. 20)",
    "a": "amplitude_deg", "f": "frequency_hz",
}
#: coefficient name -> unit suffix, eq. 19 then eq. 20
UNITS: dict[str, str] = {**model.STIFFNESS_UNITS, **model.RATIO_UNITS}
UNIT_TEXT = {"nm_per_deg": "N*m/deg", "per_deg": "1/deg", "per_hz": "1/Hz", "nm_per_deg_per_sqrt_hz": "N*m/(deg*sqrt(Hz))"}


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


@dataclass(frozen=True)
class MapRange:
    """The measured amplitude (deg) and frequency (Hz) range of the tests."""

    amplitude_deg_min: float
    amplitude_deg_max: float
    frequency_hz_min: float
    frequency_hz_max: float


@dataclass
class MapFit:
    """The characteristic map of seed 004 (eq. 19 and eq. 20) fitted to drop tests.

    coefficients / uncertainties: ``"k1"`` … ``"k13"`` in the paper's units (:data:`UNITS`);
    an uncertainty is ``inf`` where the tests do not identify the coefficient. at_bounds: names
    of coefficients on their bound (zero); not_unique: names of coefficients that another
    equally consistent solution places elsewhere (see the module docstring). Predictions take amplitude in deg and frequency in Hz
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

    @property
    def stiffness_params(self) -> np.ndarray:
        """k1..k7 of eq. 19."""
        return np.array([self.coefficients[k] for k in model.STIFFNESS_UNITS])

    @property
    def ratio_params(self) -> np.ndarray:
        """k8..k13 of eq. 20."""
        return np.array([self.coefficients[k] for k in model.RATIO_UNITS])

    def stiffness_nm_per_deg(self, amplitude_deg: ArrayLike, frequency_hz: ArrayLike) -> np.ndarray:
        """Dynamic stiffness (N·m/deg) from eq. 19."""
        return model.stiffness(self.stiffness_params, amplitude_deg, frequency_hz)

    def damping_ratio(self, amplitude_deg: ArrayLike, frequency_hz: ArrayLike) -> np.ndarray:
        """Damping ratio d = E_diss/E_el (-, seed 004 eq. 16) from eq. 19 / eq. 20."""
        return model.damping_ratio(self.stiffness_params, self.ratio_params, amplitude_deg, frequency_hz)

    def in_range(self, amplitude_deg: ArrayLike, frequency_hz: ArrayLike) -> np.ndarray:
        """True where (amplitude, frequency) lies inside the measured range (bounds included).

        The range is the rectangle of the tests' amplitude and frequency extremes, as the paper
        states it ("~20-60 Hz and ~0.15-3.2 deg", seed 004, validation section)."""
        a, f = np.broadcast_arrays(np.asarray(amplitude_deg, float), np.asarray(frequency_hz, float))
        r = self.range
        return (a >= r.amplitude_deg_min) & (a <= r.amplitude_deg_max) & (f >= r.frequency_hz_min) & (f <= r.frequency_hz_max)

    # ---- map.json ----------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """The ``map.json`` content (keys in the module docstring); non-finite numbers are null."""
        return {
            "format": FORMAT,
            "format_version": FORMAT_VERSION,
            "equations": dict(EQUATIONS),
            "coefficients": {f"{k}_{u}": _finite(self.coefficients[k]) for k, u in UNITS.items()},
            "coefficients_std": {f"{k}_{u}": _finite(self.uncertainties[k]) for k, u in UNITS.items()},
            "at_bounds": list(self.at_bounds),
            "not_unique": list(self.not_unique),
            "fit": {k: v if isinstance(v, int) else _finite(v) for k, v in asdict(self.stats).items()},
            "range": asdict(self.range),
            "excluded": [asdict(e) for e in self.excluded],
            "source": self.source,
        }

    def coefficient_table(self) -> "pd.DataFrame":
        """The coefficients as a table (``map --out map.csv|.parquet|.xlsx``): ``coefficient``,
        ``equation``, ``unit``, ``value``, ``std`` (NaN: not identifiable), ``at_bound``,
        ``not_unique``. Only ``map.json`` is read back (``validate --map``)."""
        import pandas as pd

        return pd.DataFrame([{
            "coefficient": k, "equation": "seed 004 eq. 19" if k in model.STIFFNESS_UNITS else "seed 004 eq. 20",
            "unit": UNIT_TEXT[u], "value": self.coefficients[k],
            "std": self.uncertainties[k] if math.isfinite(self.uncertainties[k]) else math.nan,
            "at_bound": k in self.at_bounds, "not_unique": k in self.not_unique} for k, u in UNITS.items()])

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
                raise DroptowerError(f"cannot write map ({exc.strerror or exc})", file=path) from None
        return text

    @classmethod
    def from_dict(cls, data: dict[str, Any], file: str | Path | None = None) -> "MapFit":
        """Build a map from ``map.json`` content; malformed content is a one-line error."""
        doc = validate(_MapFile, data, file)
        if doc.format != FORMAT or doc.format_version != FORMAT_VERSION:
            raise DroptowerError(f"not a {FORMAT} file of version {FORMAT_VERSION}", file=file)
        coefficients = {k: getattr(doc.coefficients, f"{k}_{u}") for k, u in UNITS.items()}
        stds = {k: getattr(doc.coefficients_std, f"{k}_{u}") for k, u in UNITS.items()}
        return cls(
            coefficients=coefficients,
            uncertainties={k: math.inf if v is None else v for k, v in stds.items()},
            stats=FitStats(**{k: math.inf if v is None else v for k, v in doc.fit.model_dump().items()}),
            range=MapRange(**doc.range.model_dump()),
            excluded=[ExcludedTest(**e.model_dump()) for e in doc.excluded],
            at_bounds=tuple(doc.at_bounds),
            not_unique=tuple(doc.not_unique),
            source=doc.source,
        )

    @classmethod
    def from_json(cls, path: str | Path) -> "MapFit":
        """Read ``map.json``; a missing, unreadable or malformed file is a one-line error."""
        path = Path(path)
        try:
            data = json.loads(path.read_text())
        except FileNotFoundError:
            raise DroptowerError("file not found", file=path) from None
        except json.JSONDecodeError as exc:
            raise DroptowerError(f"not valid JSON ({exc})", file=path) from None
        except (OSError, UnicodeDecodeError) as exc:
            raise DroptowerError(f"cannot read file ({exc})", file=path) from None
        if not isinstance(data, dict):
            raise DroptowerError("not a map file (expected a JSON object)", file=path)
        return cls.from_dict(data, path)

    # ---- text summary ------------------------------------------------------------------
    def summary(self) -> str:
        """Human-readable summary: coefficients ± uncertainty, errors, range, exclusions."""
        s, r = self.stats, self.range
        lines = [
            f"characteristic map (seed 004 eq. 19, eq. 20) from {self.source or 'results'}: "
            f"{s.n_tests} tests used, {len(self.excluded)} excluded",
            f"measured range: amplitude {r.amplitude_deg_min:.3g}-{r.amplitude_deg_max:.3g} deg, "
            f"frequency {r.frequency_hz_min:.4g}-{r.frequency_hz_max:.4g} Hz",
            "eq. 19  c(a, f) = k1*10^(-k2*a) + k3*10^(-k4*a) + k5*sqrt(f) + k6*10^(-k7*f)  [N*m/deg]",
            *self._coefficient_lines(model.STIFFNESS_UNITS),
            f"  stiffness error: rms {s.stiffness_rms_error_pct:.2f} %, max {s.stiffness_max_error_pct:.2f} %"
            f" (condition number {s.stiffness_condition_number:.3g})",
            "eq. 20  c/d(a) = k8*10^(-k9*a) + k10*10^(-k11*a) + k12*10^(-k13*a)  [N*m/deg]",
            *self._coefficient_lines(model.RATIO_UNITS),
            f"  damping ratio error: rms {s.damping_ratio_rms_error_pct:.2f} %, max {s.damping_ratio_max_error_pct:.2f} %"
            f" (condition number {s.damping_condition_number:.3g})",
        ]
        poor = [k for k in UNITS if not abs(self.uncertainties[k]) <= 0.5 * abs(self.coefficients[k])]
        if poor:
            lines.append(f"poorly identified (uncertainty > 50 % of the value): {', '.join(poor)}")
        if self.not_unique:
            lines.append(f"not unique (another solution fits within the 95 % confidence region): {', '.join(self.not_unique)}")
        if self.excluded:
            lines.append("excluded tests:")
            lines += [f"  {e.test}: {e.reason}" for e in self.excluded]
        return "\n".join(lines)

    def _coefficient_lines(self, units: dict[str, str]) -> list[str]:
        out = []
        for k, u in units.items():
            std = self.uncertainties[k]
            std_text = f"{std:.3g}" if math.isfinite(std) else "not identifiable"
            bound = "  (at bound)" if k in self.at_bounds else ""
            out.append(f"  {k:>3} = {self.coefficients[k]:.5g} ± {std_text} {UNIT_TEXT[u]}{bound}")
        return out


def _finite(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None


# ---- map.json schema (pydantic), so a hand-edited or truncated file gives a one-line error ----
_Coefficients = create_model("coefficients", __base__=StrictModel, **{f"{k}_{u}": (float, ...) for k, u in UNITS.items()})
_CoefficientsStd = create_model("coefficients_std", __base__=StrictModel,
                                **{f"{k}_{u}": (Optional[float], ...) for k, u in UNITS.items()})
_Fit = create_model("fit", __base__=StrictModel, n_tests=(int, ...),
                    **{k: (Optional[float], ...) for k in FitStats.__dataclass_fields__ if k != "n_tests"})
_Range = create_model("range", __base__=StrictModel, **{k: (float, ...) for k in MapRange.__dataclass_fields__})


class _Excluded(StrictModel):
    test: str
    reason: str


class _MapFile(StrictModel):
    format: str
    format_version: int
    equations: dict[str, str] = {}
    coefficients: _Coefficients  # type: ignore[valid-type]
    coefficients_std: _CoefficientsStd  # type: ignore[valid-type]
    at_bounds: list[str] = []
    not_unique: list[str] = []
    fit: _Fit  # type: ignore[valid-type]
    range: _Range  # type: ignore[valid-type]
    excluded: list[_Excluded] = []
    source: Optional[str] = None
