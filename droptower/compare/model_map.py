"""The model-based characteristic map: an identified coupling evaluated on the virtual servo bench
over amplitude x frequency, beside the paper's map (docs/routes.md, docs/theory.md#damping-measures).

The paper's map (Rapp et al. 2022, eq. 19/20) is fitted to first-cycle readings of the decays and
inherits their bias (docs/theory.md#first-cycle). The model-based route reads the same campaign
through a coupling model re-simulating every decay (:func:`~droptower.identify.dropfit.identify_drops`), then asks the
model what a servo bench would measure. Per grid point (amplitude φ̂, frequency f):

- ``storage_stiffness_nm_per_deg`` K', ``loss_stiffness_nm_per_deg`` K'', ``loss_factor``
  η = K''/K' and ``dynamic_stiffness_nm_per_deg`` |K*|: the first harmonic of whole steady
  cycles, evaluated exactly as the bench does (:mod:`droptower.servo.evaluate`: the same
  history, acquisition rate and smoothing), so the model map and a bench run on the same
  coupling agree to the bench's own repeatability;
- ``drop_tower_equivalent_damping_ratio`` d = E_diss/E_el (Rapp et al. 2022, eq. 16) of the linear
  Kelvin-Voigt coupling with this η (docs/theory.md#damping-measures): what validation compares with
  the servo's d, like with like; it equals the d of the complex root of J s² + K*(s) = 0 for a
  Kelvin-Voigt coupling, and comes within K*(s) vs K*(iω) of it for relaxation faster than the
  oscillation;
- ``lehr_damping`` D = δ/ω0 = r/√(1 + r²) of the same coupling, r = δ/ω.

Confidence bands (``*_band_lo`` / ``*_band_hi``, 95 %) propagate the identification's parameter
covariance, cluster-robust by test (:func:`drop_covariance`), to every quantity by the delta
method. The covariance is stored as sigma-point parameter sets: the coupling's raw parameters at
ẑ + ε·u_k for the principal directions u_k = √λ_k·v_k of the covariance of the optimised
variables z, so var(q) = Σ_k ((q(P_k) − q(P_0))/ε)² needs no family at evaluation time, and all
sets of all points run in one batched bench call per frequency. Why not a bootstrap over tests:
docs/routes.md.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike

from droptower import sdof
from droptower.deprecation import renamed_keywords
from droptower.errors import DroptowerError, readable_file
from droptower.jsonsafe import json_safe
from droptower.maps.mapfit import MapRange, read_json_object
from droptower.rates import RIG_SAMPLE_RATE_HZ, SERVO_SAMPLE_RATE_HZ
from droptower.rheology import Coupling

FORMAT = "droptower-model-map"
FORMAT_VERSION = 1
#: two-sided 95 % normal quantile of the bands
Z95 = 1.959963984540054
#: sigma-point step in units of a principal standard deviation: small enough that the quantities
#: are linear over it, large enough that the bench's own repeatability (~1e-9) is far below it
BAND_STEP = 0.1
#: the quantities per grid point (first harmonic), with their bands where the map has a covariance
QUANTITIES = ("storage_stiffness_nm_per_deg", "loss_stiffness_nm_per_deg", "loss_factor",
              "dynamic_stiffness_nm_per_deg", "drop_tower_equivalent_damping_ratio", "lehr_damping")
PAPER_ROUTE = "paper map, eq. 19/20"
#: the coverage factor of the expanded uncertainties ``<q>_U95`` with the inputs (GUM 6.2.1, k = 2)
COVERAGE_K = 2.0
#: parameter sets x decays simulated per core call for the bands' Jacobian (memory: a decay holds
#: ~10^4 steps of angle and torque)
MAX_DECAYS_PER_CALL = 1500


def route_name(family: str) -> str:
    """The model-based route's name as every output shows it."""
    return f"model-based map, {family}"


def damping_measures(loss_factor: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """(d, D): Rapp's drop-tower damping ratio d = E_diss/E_el (eq. 16) and Lehr's D = δ/ω0 of
    the linear Kelvin-Voigt coupling with loss factor η (docs/theory.md#damping-measures)."""
    r = sdof.decay_ratio_from_loss_factor(loss_factor)
    return sdof.drop_tower_equivalent_damping_ratio(loss_factor), r / np.sqrt(1.0 + r * r)


def _quantities(k: np.ndarray) -> dict[str, np.ndarray]:
    """The QUANTITIES of complex first-harmonic stiffnesses K* (N*m/rad)."""
    eta = k.imag / k.real
    d, lehr = damping_measures(eta)
    return {"storage_stiffness_nm_per_deg": np.radians(k.real), "loss_stiffness_nm_per_deg": np.radians(k.imag),
            "loss_factor": eta, "dynamic_stiffness_nm_per_deg": np.radians(np.abs(k)),
            "drop_tower_equivalent_damping_ratio": d, "lehr_damping": lehr}


def bench_first_harmonics(elements: Coupling, params: np.ndarray, amplitude_deg: ArrayLike,
                          frequency_hz: ArrayLike) -> np.ndarray:
    """Complex first-harmonic stiffness K* (N*m/rad), shape (S, P), of every parameter set (rows
    of ``params`` (S, n), raw parameters of ``elements``' kernels) at every point (P,), unloaded,
    evaluated as the servo bench does. All sets and amplitudes of one frequency run as one batch."""
    from droptower.servo import bench

    a = np.atleast_1d(np.asarray(amplitude_deg, float))
    f = np.broadcast_to(np.asarray(frequency_hz, float), a.shape)
    if not (np.all(np.isfinite(a) & (a > 0)) and np.all(np.isfinite(f) & (f > 0))):
        raise DroptowerError("model map: amplitudes and frequencies must be positive and finite")
    params = np.atleast_2d(np.asarray(params, float))
    n_sets = params.shape[0]
    out = np.empty((n_sets, a.size), complex)
    rate = max(SERVO_SAMPLE_RATE_HZ, 40.0 * float(f.max()))  # at least 40 samples per cycle, as identify's servo grid
    for freq in np.unique(f):
        cols = np.flatnonzero(f == freq)
        amps = np.radians(a[cols])
        rows = Coupling(elements.elements, name=elements.name, params=np.repeat(params, cols.size, axis=0))
        fine = max(RIG_SAMPLE_RATE_HZ, bench.MIN_STEPS_PER_CYCLE * freq)
        substeps = max(1, math.ceil(fine / rate - 1e-9))
        _, evals, *_ = bench._run_frequency(rows, float(freq), np.tile(amps, n_sets), 0.0, rate, substeps, 5, 5, 2,
                                            True)
        out[:, cols] = np.array([e.complex_stiffness_nm_per_rad for e in evals]).reshape(n_sets, cols.size)
    return out


@dataclass
class ModelMap:
    """A coupling's servo-equivalent characteristic map with confidence bands (module docstring).

    coupling: the identified coupling (one parameter set); band_sets: (K, n) raw parameter sets
    at ẑ + ε·u_k (None: no covariance, no bands); band_method: how the covariance was obtained;
    range: the campaign's tested points (in_range: inside their hull); family: the model's name;
    identification: the fit's verdict and errors, as reported; grid: the evaluated table on the
    map's own grid (:meth:`evaluate`'s columns); input_uncertainty, input_sets: the rig's input
    uncertainties and each input's shifted parameter set (one standard uncertainty; then
    :meth:`evaluate` adds ``<q>_u_inputs`` and ``<q>_U95``, k = 2, the fit's and the inputs' together)."""

    coupling: Coupling
    family: str
    range: MapRange
    band_sets: np.ndarray | None = None
    band_step: float = BAND_STEP
    band_method: str | None = None
    identification: dict[str, Any] = field(default_factory=dict)
    source: str | None = None
    grid: pd.DataFrame | None = None
    _cache: dict[str, Any] = field(default_factory=dict, repr=False)
    #: the rig's input uncertainties the map was built with (``RigUncertainty.model_dump()``) and
    #: each input's shifted raw parameter set (:func:`droptower.uncertainty.route.route_input_sets`)
    input_uncertainty: dict[str, Any] | None = None
    input_sets: dict[str, np.ndarray] | None = None

    @property
    def route(self) -> str:
        return route_name(self.family)

    @property
    def has_bands(self) -> bool:
        return self.band_sets is not None and len(self.band_sets) > 0

    def evaluate(self, amplitude_deg: ArrayLike, frequency_hz: ArrayLike) -> pd.DataFrame:
        """One row per point: amplitude_deg, frequency_hz, the QUANTITIES and, with a covariance,
        ``<q>_std`` and the 95 % band ``<q>_band_lo`` / ``<q>_band_hi``; ``in_range``."""
        a, f = np.broadcast_arrays(np.asarray(amplitude_deg, float), np.asarray(frequency_hz, float))
        a, f = a.ravel(), f.ravel()
        key = (a.tobytes(), f.tobytes())
        if self._cache.get("key") == key:
            return self._cache["table"]
        n_bands = len(self.band_sets) if self.has_bands else 0
        inputs = list((self.input_sets or {}).values())
        sets = np.vstack([self.coupling.params[:1], *([self.band_sets] if n_bands else []),
                          *[np.asarray(v, float)[None] for v in inputs]])
        k = bench_first_harmonics(self.coupling, sets, a, f)  # one batched call: nominal, bands, inputs
        table = pd.DataFrame({"amplitude_deg": a, "frequency_hz": f})
        nominal = _quantities(k[0])
        spread = [_quantities(row) for row in k[1:1 + n_bands]]
        moved = [_quantities(row) for row in k[1 + n_bands:]]
        for q in QUANTITIES:
            table[q] = nominal[q]
            if self.has_bands:
                std = np.sqrt(sum(((s[q] - nominal[q]) / self.band_step) ** 2 for s in spread))
                table[f"{q}_std"] = std
                table[f"{q}_band_lo"] = nominal[q] - Z95 * std
                table[f"{q}_band_hi"] = nominal[q] + Z95 * std
            if moved:  # each input's shift is its contribution c_i·u(x_i) (GUM 5.1.3); independent inputs
                u_in = np.sqrt(sum((m[q] - nominal[q]) ** 2 for m in moved))
                table[f"{q}_u_inputs"] = u_in
                table[f"{q}_U95"] = COVERAGE_K * np.hypot(table[f"{q}_std"] if self.has_bands else 0.0, u_in)
        table["in_range"] = self.in_range(a, f)
        self._cache.update(key=key, table=table)
        return table

    # the interface validation reads a map through (as MapFit's)
    def stiffness_nm_per_deg(self, amplitude_deg: ArrayLike, frequency_hz: ArrayLike) -> np.ndarray:
        """The model's storage stiffness K' (N*m/deg), compared with the servo's K'."""
        return self.evaluate(amplitude_deg, frequency_hz)["storage_stiffness_nm_per_deg"].to_numpy()

    def damping_ratio(self, amplitude_deg: ArrayLike, frequency_hz: ArrayLike) -> np.ndarray:
        """The drop-tower-equivalent damping ratio d of the model's loss factor (-)."""
        return self.evaluate(amplitude_deg, frequency_hz)["drop_tower_equivalent_damping_ratio"].to_numpy()

    def in_range(self, amplitude_deg: ArrayLike, frequency_hz: ArrayLike) -> np.ndarray:
        return self.range.in_hull(amplitude_deg, frequency_hz)

    def in_rectangle(self, amplitude_deg: ArrayLike, frequency_hz: ArrayLike) -> np.ndarray:
        return self.range.in_rectangle(amplitude_deg, frequency_hz)

    def evaluate_grid(self, amplitudes_deg: Sequence[float] | None = None,
                      frequencies_hz: Sequence[float] | None = None, n: tuple[int, int] = (8, 5)) -> pd.DataFrame:
        """Evaluate the map on amplitudes x frequencies (default: ``n`` log-spaced values over the
        tested rectangle) and keep it as :attr:`grid`."""
        r = self.range
        a = np.geomspace(r.amplitude_deg_min, r.amplitude_deg_max, n[0]) if amplitudes_deg is None else amplitudes_deg
        f = np.geomspace(r.frequency_hz_min, r.frequency_hz_max, n[1]) if frequencies_hz is None else frequencies_hz
        aa, ff = np.meshgrid(np.asarray(a, float), np.asarray(f, float), indexing="ij")
        self.grid = self.evaluate(aa, ff)
        return self.grid

    # ---- model_map.json -------------------------------------------------------------------
    def input_shares(self, amplitude_deg: ArrayLike, frequency_hz: ArrayLike) -> dict[str, dict[str, np.ndarray]]:
        """Each input's standard-uncertainty share of the map's quantities at the points: quantity
        (``storage_stiffness_nm_per_deg``, ``loss_factor``, ...) -> input key -> Δq (P,), signed:
        the bench run on the input's shifted set
        (:func:`droptower.uncertainty.route.route_input_sets`) minus the nominal one (the
        contribution c_i·u(x_i), GUM 5.1.3); empty where no input uncertainty was given."""
        if not self.input_sets:
            return {q: {} for q in QUANTITIES}
        keys = list(self.input_sets)
        sets = np.vstack([self.coupling.params[:1], *[self.input_sets[k][None] for k in keys]])
        k = bench_first_harmonics(self.coupling, sets, amplitude_deg, frequency_hz)
        nominal = _quantities(k[0])
        moved = [_quantities(row) for row in k[1:]]
        return {q: {key: m[q] - nominal[q] for key, m in zip(keys, moved)} for q in QUANTITIES}

    def to_dict(self) -> dict[str, Any]:
        """JSON content: format, route, family, coupling (TOML text), raw parameters of the
        nominal and the band sets, band method, range, identification and the evaluated grid."""
        from droptower.rheology import coupling_to_toml

        r = self.range
        grid = None if self.grid is None else json_safe(self.grid.to_dict(orient="list"))
        return {"format": FORMAT, "format_version": FORMAT_VERSION, "route": self.route, "family": self.family,
                "coupling_toml": coupling_to_toml(self.coupling),
                "parameters_raw": self.coupling.params[0].tolist(),
                "band_sets_raw": None if self.band_sets is None else np.asarray(self.band_sets).tolist(),
                "band_step": self.band_step, "band_method": self.band_method, "band_level": 0.95,
                "range": {"amplitude_deg_min": r.amplitude_deg_min, "amplitude_deg_max": r.amplitude_deg_max,
                          "frequency_hz_min": r.frequency_hz_min, "frequency_hz_max": r.frequency_hz_max,
                          "hull_amplitude_deg_frequency_hz": [list(v) for v in r.hull]},
                "identification": json_safe(self.identification), "source": self.source, "grid": grid,
                "input_uncertainty": json_safe(self.input_uncertainty),
                "input_sets_raw": None if not self.input_sets else {k: np.asarray(v, float).tolist()
                                                                    for k, v in self.input_sets.items()}}

    def to_json(self, path: str | Path | None = None) -> str:
        """The map as JSON text; with ``path``, also written there (atomically)."""
        from droptower.io.droptower_log import atomic_write

        text = json.dumps(self.to_dict(), indent=1) + "\n"
        if path is not None:
            atomic_write(path, lambda tmp: Path(tmp).write_text(text))
        return text

    @classmethod
    def from_dict(cls, data: dict[str, Any], file: str | Path | None = None) -> "ModelMap":
        import tomllib

        from droptower.rheology import parse_coupling

        if not isinstance(data, dict) or data.get("format") != FORMAT or data.get("format_version") != FORMAT_VERSION:
            raise DroptowerError(f"not a {FORMAT} file of version {FORMAT_VERSION}", file=file)
        try:
            base = parse_coupling(tomllib.loads(data["coupling_toml"]), file)
            params = np.asarray(data["parameters_raw"], float)[None, :]
            coupling = Coupling(base.elements, name=base.name, description=base.description, params=params)
            bands = data.get("band_sets_raw")
            r = data["range"]
            rng = MapRange(float(r["amplitude_deg_min"]), float(r["amplitude_deg_max"]), float(r["frequency_hz_min"]),
                           float(r["frequency_hz_max"]),
                           tuple((float(x), float(y)) for x, y in r.get("hull_amplitude_deg_frequency_hz", [])))
            out = cls(coupling, str(data["family"]), rng, None if bands is None else np.asarray(bands, float),
                      float(data.get("band_step", BAND_STEP)), data.get("band_method"),
                      data.get("identification") or {}, data.get("source"))
        except (KeyError, TypeError, ValueError, tomllib.TOMLDecodeError) as exc:
            raise DroptowerError(f"malformed model map ({type(exc).__name__}: {exc})", file=file) from None
        try:
            out.input_uncertainty = data.get("input_uncertainty") or None
            sets = data.get("input_sets_raw") or {}
            out.input_sets = {str(k): np.asarray(v, float) for k, v in sets.items()} or None
            if out.input_sets and any(v.shape != params.shape[1:] for v in out.input_sets.values()):
                raise ValueError("an input set's length differs from the coupling's parameters")
        except (AttributeError, TypeError, ValueError) as exc:
            raise DroptowerError(f"malformed model map: input_sets_raw ({exc})", file=file) from None
        if data.get("grid"):
            out.grid = pd.DataFrame(data["grid"])
        return out

    @classmethod
    def from_json(cls, path: str | Path) -> "ModelMap":
        """Read ``model_map.json``; a missing, unreadable or malformed file is a one-line error."""
        path = readable_file(path)
        return cls.from_dict(read_json_object(path, "a model map file"), path)

    def summary(self) -> str:
        """A few lines: the route, the identification's verdict, the bands' method, the grid's span."""
        ident = self.identification
        lines = [f"{self.route}: coupling {self.coupling.name}"
                 + (f", {ident['verdict']}" if ident.get("verdict") else "")
                 + (f" (angle nRMSE {100 * ident['angle_nrmse']:.3g} %)" if ident.get("angle_nrmse") is not None else "")]
        lines.append(f"bands: {self.band_method}" if self.has_bands else "bands: none (no parameter covariance given)")
        if self.input_sets:
            lines.append(f"inputs: {', '.join(self.input_sets)} (one standard uncertainty each; U95 = 2*sqrt(u_fit^2 + "
                         "u_inputs^2) in the grid's *_U95)")
        if self.grid is not None:
            g = self.grid
            lines.append(f"grid: {g['amplitude_deg'].nunique()} amplitudes x {g['frequency_hz'].nunique()} frequencies; "
                         f"K' {g['storage_stiffness_nm_per_deg'].min():.4g}-{g['storage_stiffness_nm_per_deg'].max():.4g} "
                         f"N*m/deg, loss factor {g['loss_factor'].min():.3g}-{g['loss_factor'].max():.3g}, "
                         f"d {g['drop_tower_equivalent_damping_ratio'].min():.3g}-"
                         f"{g['drop_tower_equivalent_damping_ratio'].max():.3g}")
        return "\n".join(lines)


def sigma_point_sets(family: Any, values: np.ndarray, free: np.ndarray, cov_z: np.ndarray,
                     step: float = BAND_STEP) -> np.ndarray:
    """Raw parameter sets (K, n_raw) of ``family`` at ẑ + step·√λ_k·v_k for the eigenpairs
    (λ_k, v_k) of ``cov_z`` (free parameters, optimised variables); λ_k ≤ 0 are dropped."""
    params = family.parameters
    idx = np.flatnonzero(free)
    z0 = np.array([params[i].to_z(values[i]) for i in idx])
    lam, vec = np.linalg.eigh(0.5 * (cov_z + cov_z.T))
    rows = []
    for lk, vk in zip(lam, vec.T):
        if lk <= 1e-14 * max(lam.max(), 1e-300):
            continue
        z = z0 + step * math.sqrt(lk) * vk
        v = np.array(values, float)
        v[idx] = [params[i].to_value(zi) for i, zi in zip(idx, z)]
        rows.append(family.coupling(v).params[0])
    return np.array(rows).reshape(len(rows), -1)


def drop_covariance(ident: Any, decays: list, settings: Any, step: float = 1e-4) -> tuple[np.ndarray, np.ndarray]:
    """(free mask, covariance of the optimised variables z) of a drop-test identification
    (:class:`~droptower.identify.result.Identification` from drop tests), cluster-robust by test: the
    sandwich (J'J)⁺ (Σ_tests J_t' r_t r_t' J_t) (J'J)⁺ · G/(G − 1) on the fitting tests' residual
    and its forward-difference Jacobian (batched calls of the core): the scatter between tests,
    whatever the correlation within a test. The identification's reported standard errors add the
    integration step's bias, which does not shrink with more tests and is not in the bands."""
    from droptower.identify.dropfit import DropProblem
    from droptower.identify.engine.local import LocalFit

    used = set(ident.tests_used)
    fitting = [d for d in decays if d.name in used]
    if len(fitting) < 2:
        raise DroptowerError(f"model map bands: {len(fitting)} of the identification's fitting tests are among "
                             "the given logs; give the logs it was fitted to")
    problem = DropProblem(ident.family_model, fitting, settings)
    params = ident.family_model.parameters
    values = ident.params.vector()
    free = np.isfinite(ident.params.stderr_vector())
    idx = np.flatnonzero(free)
    z0 = np.array([params[i].to_z(values[i]) for i in idx])
    rows = np.tile(values, (idx.size + 1, 1))
    for j, i in enumerate(idx):
        rows[j + 1, i] = params[i].to_value(z0[j] + step)
    # parameter sets x tests per core call bounded (a 450-test campaign's decays are long)
    per_call = max(1, MAX_DECAYS_PER_CALL // len(fitting))
    res = np.concatenate([problem.residuals(rows[i:i + per_call]) for i in range(0, len(rows), per_call)])
    jac = ((res[1:] - res[0]) / step).T
    sol = LocalFit(params, values, free, res[0], jac, [], 0, 0, True, "")
    return free, sol.covariance_z_clustered(problem.test_of_residual)


CLUSTER_METHOD = ("95 %, delta method on the identification's parameter covariance, cluster-robust by test "
                  "(sandwich over the fitting tests, G/(G-1))")


def model_map_from_identification(ident: Any, decays: list, settings: Any, tested: MapRange | None = None,
                                  bands: bool = True, source: str | None = None, uncertainty: Any = None,
                                  lever_length_m: float | None = None,
                                  laser_radius_m: float | None = None) -> ModelMap:
    """The model map of a drop-test identification, with cluster-robust 95 % bands (``bands``),
    over the tested range ``tested`` (default: the decays' first-cycle amplitudes and
    frequencies). Evaluate it with :meth:`ModelMap.evaluate_grid`.

    With ``uncertainty`` (a :class:`~droptower.rig.uncertainty.RigUncertainty`) the map also holds
    each given input's shifted parameter set (:func:`droptower.uncertainty.route.route_input_sets`;
    ``lever_length_m`` and ``laser_radius_m``, m, are the nominal values the logs were read with,
    needed when their uncertainty is given) and the uncertainties themselves."""
    coupling = ident.coupling
    if tested is None:
        tested = MapRange.of_points([math.degrees(d.amplitude_rad) for d in decays], [d.frequency_hz for d in decays])
    band_sets = None
    if bands:
        free, cov = drop_covariance(ident, decays, settings)
        band_sets = sigma_point_sets(ident.family_model, ident.params.vector(), free, cov)
    verdict = ident.verdict.to_dict() if ident.verdict is not None else {}
    info = {"model": ident.family, "converged": ident.converged, "verdict": verdict.get("verdict"),
            "angle_nrmse": ident.fit_error.get("angle_nrmse"), "tests_used": len(ident.tests_used),
            "wall_s": ident.wall_s,
            "parameters": {n: {"value": p.value, "std_error": p.stderr} for n, p in ident.params.items()}}
    mm = ModelMap(coupling, ident.family, tested, band_sets, BAND_STEP, CLUSTER_METHOD if bands else None, info,
                  source)
    if uncertainty is not None:
        from droptower.uncertainty.route import route_input_sets

        mm.input_sets = route_input_sets(ident, decays, settings, uncertainty, lever_length_m=lever_length_m,
                                         laser_radius_m=laser_radius_m) or None
        mm.input_uncertainty = uncertainty.model_dump(exclude_none=True)
    return mm


def model_map_from_coupling(coupling: Coupling, tested: MapRange, family: str | None = None,
                            source: str | None = None) -> ModelMap:
    """The model map of a coupling given as it is (a coupling file): no covariance, no bands."""
    if coupling.n_sets != 1:
        raise DroptowerError(f"model map: the coupling has {coupling.n_sets} parameter sets; give one")
    return ModelMap(coupling, family or coupling.name or "coupling", tested, source=source)


#: excluded logs named one by one in the notes of :func:`build_model_map` (the rest are counted)
EXCLUDED_NAMED = 5


@renamed_keywords(model="family")
def build_model_map(results: str | Path, fit: Any, *, family: str | None = None, template: str | None = None,
                    coupling_file: str | Path | None = None, campaign: Any = None,
                    on_note: Callable[[str], None] | None = None,
                    on_progress: Callable[[str], None] | None = None, rig: Any = None,
                    roles: dict[str, str] | None = None, sensor_radius_m: float | None = None,
                    conditions: Any = None, table: pd.DataFrame | None = None, inertia_kgm2: float | None = None,
                    lever_length_m: float | None = None, uncertainty: Any = None) -> ModelMap:
    """The model-based map beside the paper's map ``fit`` (whose measured range it shares),
    evaluated on its grid.

    Parameters
    ----------
    results : str or path
        What the paper's map was fitted to: a campaign folder (its logs and its rig), a lab's
        folder of logs, or a results table whose ``file`` column names its logs.
    fit : MapFit
        The paper's map.
    family : str, optional
        Identify this drop-test family from the logs (``model`` in release 0.1: deprecated)
        (:func:`~droptower.identify.drop_campaign.identify_from_drop_tests`); the map gets 95 % bands,
        cluster-robust by test.
    template : str, optional
        With ``family="template"``: the coupling whose structure is fitted.
    coupling_file : str or path, optional
        Instead of ``family``: a coupling file as it is, or the JSON of a drop-test
        identification that wrote one (no bands: no covariance).
    campaign : DropCampaign, optional
        The logs already read (:func:`~droptower.identify.drop_campaign.read_drop_tests`).
    on_note : callable, optional
        Called with a note: the excluded logs, a poor fit.
    on_progress : callable, optional
        Called with a line on what is being done.
    rig : str or RigConfig, optional
        The rig of a lab's logs (lever length, laser radius, fixtures; a campaign folder's own
        by default).
    roles : dict, optional
        Channel role -> ``NAME[:UNIT]`` for reading a lab's logs.
    sensor_radius_m : float, optional
        Laser spot radius (m) for a distance channel.
    conditions : Conditions, optional
        Per-file conditions (each log's fixture or inertia, drop mass and height).
    table : DataFrame, optional
        The results table already read (for a results table's per-file inertia).
    inertia_kgm2, lever_length_m : float, optional
        Every log's inertia (kg*m^2) and lever length (m), over the logs', the conditions' and the rig's.
    uncertainty : RigUncertainty, optional
        The rig's input uncertainties: with ``family``, the map holds each input's shift of the
        identification and its ``<q>_U95`` the inputs' share (:mod:`droptower.uncertainty.route`).

    Returns
    -------
    ModelMap
        Evaluated on its grid (:meth:`ModelMap.evaluate_grid`).
    """
    results = Path(results)
    if (family is None) == (coupling_file is None):
        raise DroptowerError("give `family` (identify from the logs) or `coupling_file` (a coupling as it is), one of them")
    if coupling_file is not None:
        from droptower.rheology import load_coupling

        coupling_file, family = Path(coupling_file), None
        if coupling_file.suffix.lower() == ".json":  # a drop-test identification's JSON: the coupling it wrote
            from droptower.maps.mapfit import read_json_object

            doc = read_json_object(coupling_file, "a drop-test identification's JSON")
            if not doc.get("coupling_file"):
                raise DroptowerError("the identification wrote no coupling (run it with an output coupling file)",
                                     file=coupling_file)
            family = doc.get("family", doc.get("model"))  # "model": an identification JSON of release 0.1
            coupling_file = Path(doc["coupling_file"])
        mm = model_map_from_coupling(load_coupling(coupling_file), fit.range, family=family, source=str(coupling_file))
    else:
        from droptower.identify.drop_campaign import identify_from_drop_tests

        if campaign is None:
            campaign = read_logs_for_model(results, family, template=template, rig=rig, roles=roles,
                                           sensor_radius_m=sensor_radius_m, conditions=conditions, table=table,
                                           inertia_kgm2=inertia_kgm2, lever_length_m=lever_length_m)
            for e in campaign.excluded[:EXCLUDED_NAMED] if on_note is not None else []:
                on_note(f"excluded {e['file']}: {e['reason']}")
            if len(campaign.excluded) > EXCLUDED_NAMED and on_note is not None:
                on_note(f"excluded {len(campaign.excluded) - EXCLUDED_NAMED} more test(s)")
        if on_progress is not None:
            on_progress(f"map: identifying {family} from {len(campaign.decays)} drop test(s) for the model-based map ...")
        ident = identify_from_drop_tests(campaign, family)
        if not ident.converged:
            raise DroptowerError(f"family {family}: the fit to the drop tests did not converge ({ident.message}); "
                                 "no model-based map")
        lever, laser = (None, None)
        if uncertainty is not None:
            from droptower.uncertainty.route import nominal_geometry

            lever, laser = nominal_geometry(campaign.decays, campaign.read)
        mm = model_map_from_identification(ident, campaign.decays, campaign.settings, tested=fit.range,
                                           source=str(results), uncertainty=uncertainty, lever_length_m=lever,
                                           laser_radius_m=laser)
        if ident.verdict is not None and ident.verdict.poor and on_note is not None:
            on_note(f"note: family {family} is a poor fit ({'; '.join(ident.verdict.reasons)}): its map cannot be "
                    "trusted beyond the paper's")
    mm.evaluate_grid()
    return mm


@renamed_keywords(model="family")
def read_logs_for_model(results: str | Path, family: str, *, template: str | None = None, rig: Any = None,
                        roles: dict[str, str] | None = None, sensor_radius_m: float | None = None,
                        conditions: Any = None, table: pd.DataFrame | None = None, holdout_fraction: float = 0.0,
                        options: dict[str, Any] | None = None, inertia_kgm2: float | None = None,
                        lever_length_m: float | None = None) -> Any:
    """The drop tests a model-based map identifies from (:func:`~droptower.identify.drop_campaign.read_drop_tests`):
    a campaign folder's ``logs/`` with its own rig (unless ``rig``), a lab's folder of logs (the
    conditions table beside them left out), or the logs a results table names (``file``),
    each with the inertia its row gives where no ``conditions`` do.

    Parameters
    ----------
    results : path
        Campaign folder, folder of logs or results table.
    family : str
        The family to be fitted.
    template : str, optional
        With ``family="template"``: the coupling whose structure is fitted.
    rig : str or RigConfig, optional
        The rig (lever length m, laser radius m, fixtures).
    roles : dict, optional
        Channel role -> ``NAME[:UNIT]``.
    sensor_radius_m : float, optional
        Laser spot radius (m).
    conditions : Conditions, optional
        Per-file conditions.
    table : DataFrame, optional
        The results table already read.
    holdout_fraction : float
        Share of the tests held out (0 for a map: every test fits).
    options : dict, optional
        The family's, the fit's and the reading's options (as :func:`~droptower.identify.drop_campaign.read_drop_tests`).
    inertia_kgm2, lever_length_m : float, optional
        Every log's inertia (kg*m^2) and lever length (m), over what the logs, the table and the rig say.

    Returns
    -------
    DropCampaign
        The decays, the excluded logs with their reasons, the settings.
    """
    from droptower.identify.drop_campaign import DropCampaign, read_drop_tests
    from droptower.maps.fromlogs import log_files

    results = Path(results)
    common = dict(family=family, template=template, holdout_fraction=holdout_fraction, roles=roles,
                  sensor_radius_m=sensor_radius_m, conditions=conditions, options=options, lever_length_m=lever_length_m)
    if results.is_dir():
        from droptower.campaign.folder import saved_inputs

        if (results / "logs").is_dir() and (results / "manifest.json").is_file():
            inputs = saved_inputs(results)
            own = str(inputs["rig"]) if "rig" in inputs else None
            return read_drop_tests(results / "logs", rig=rig if rig is not None else own, inertia_kgm2=inertia_kgm2,
                                   **common)
        skip = [conditions.source] if conditions is not None and Path(str(conditions.source)).is_file() else []
        return read_drop_tests(log_files(results, exclude=skip), rig=rig, inertia_kgm2=inertia_kgm2, **common)
    if table is None:
        from droptower.maps.results import read_results

        table = read_results(results)
    if "file" not in table.columns:
        raise DroptowerError("`family` identifies from the logs: the results table has no 'file' column naming them",
                             file=results)
    files = [str(f) for f in dict.fromkeys(table["file"].dropna().astype(str)) if f.strip()]
    found = {f: next((c for c in (Path(f), results.parent / f) if c.is_file()), None) for f in files}
    missing = [f for f, p in found.items() if p is None]
    if len(missing) == len(files):
        raise DroptowerError(f"`family` identifies from the logs the results table names, and none of its {len(files)} "
                             f"log(s) was found (e.g. {files[0] if files else '-'}; relative to the table's folder or "
                             "the working folder)", file=results)
    inertia = {}
    if conditions is None and inertia_kgm2 is None and "inertia_kgm2" in table.columns:
        by_file = table.drop_duplicates("file").set_index(table.drop_duplicates("file")["file"].astype(str))
        inertia = pd.to_numeric(by_file["inertia_kgm2"], errors="coerce").to_dict()
    groups: dict[float | None, list[Path]] = {}
    for f, p in found.items():
        if p is not None:
            j = inertia_kgm2 if inertia_kgm2 is not None else inertia.get(f)
            known = j is not None and math.isfinite(j)  # a row without a number: the log's own metadata says
            groups.setdefault(float(j) if known else None, []).append(p)
    parts = [read_drop_tests(paths, rig=rig, inertia_kgm2=j, **common) for j, paths in groups.items()]
    first = parts[0]
    excluded = [e for part in parts for e in part.excluded]
    excluded += [{"file": f, "reason": "log not found"} for f in missing]
    return DropCampaign([d for part in parts for d in part.decays], excluded, first.settings, first.options, first.read,
                        [p for part in parts for p in part.paths])
