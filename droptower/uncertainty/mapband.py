"""Expanded uncertainties of a characteristic map (Rapp et al. 2022, eq. 19-20; docs/theory.md#map):
its coefficients and its predicted stiffness and damping ratio, the fit's share and the rig's
inputs' together (GUM, JCGM 100:2008, 5.1-5.2; docs/guide/uncertainty.md#the-map).

- The fit's share: the covariance s²(JᵀJ)⁻¹ of the map's relative residuals at its solution (the
  drops' scatter about the map, independent from drop to drop: it shrinks with repeats), through
  the map's equations to a prediction by :func:`droptower.propagation.propagate`.
- The inputs' share: an input error is *correlated* across every drop that shares it (GUM 5.2):
  one J for every drop of a fixture, one laser radius, laser calibration and sample clock for
  all. Each such input moves every drop it enters at once, by the measurement model's own closed
  forms (:mod:`droptower.uncertainty.model`): J scales the stiffness c = J(ω² + δ²) (and c/d) of
  its fixture's drops; the clock's rate scales the frequency by f_s/f_s,0 and the stiffness by its
  square; the laser's radius and calibration scale the amplitude by r_0/(r·κ_L); the damping
  ratio carries none of them. The map's coefficients follow by the sensitivity of the map's own
  least-squares minimum to the moved drops, Δp = −H⁻¹·Δ(Jᵀr) (implicit function theorem, the
  full Hessian; central differences of ± u, GUM 5.1.3), so the input's share does not average
  out with repeats. Inputs that do not enter c(φ̂, f) or d(φ̂, f) (lever
  length, drop mass and height, torque and force calibrations: the impact energy and the torque
  route only) have no share here.

u_c² = u_fit² + Σ_k u_k², the inputs independent of each other and of the fit; U95 = 2·u_c (k = 2).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike

from droptower.errors import DroptowerError
from droptower.propagation import propagate
from droptower.rig.uncertainty import RigUncertainty
from droptower.uncertainty.budget import COVERAGE_FACTOR
from droptower.uncertainty.gum import FIT

#: the inputs a map carries: name -> what of a drop it scales (see the module docstring)
MAP_INPUTS: tuple[str, ...] = ("inertia_kgm2", "sample_rate_hz", "laser_radius_m", "laser_calibration_rel")
#: the share of an input's u (and of its Δp, for a prediction) over which a sensitivity is taken by
#: central differences: first order, as the GUM's law of propagation (the map is curved over a
#: full u in a loosely determined decay exponent)
STEP = 1e-3


@dataclass(frozen=True)
class MapUncertainty:
    """A map (``map``, a :class:`~droptower.maps.MapFit`) with the uncertainty of its
    coefficients and predictions: ``sensitivity`` source -> Δp (the map's parameter vector, eq. 19
    then eq. 20, moved by one standard uncertainty of that correlated input); ``covariance`` the
    fit's covariance of the parameters (the two equations' blocks, independent fits);
    ``not_given`` the inputs the map would carry whose uncertainty was not stated (a fixture as
    ``inertia_kgm2@J``)."""

    map: object
    covariance: np.ndarray
    sensitivity: dict[str, np.ndarray]
    not_given: tuple[str, ...] = ()
    names: tuple[str, ...] = field(default=())

    def coefficient_table(self) -> pd.DataFrame:
        """One row per coefficient: ``value``, ``u_fit``, one ``u_<input>`` per given input,
        ``u_inputs`` (their root sum of squares), ``u_c``, ``U95`` (k = 2), in the coefficient's
        unit (the map's :meth:`~droptower.maps.MapFit.coefficient_table`), and ``dominant``."""
        params = _params(self.map)
        u_fit = np.sqrt(np.clip(np.diag(self.covariance), 0.0, None))
        table = pd.DataFrame({"coefficient": list(self.names), "value": params, "u_fit": u_fit})
        for source, dp in self.sensitivity.items():
            table[f"u_{source}"] = np.abs(dp)
        u_inputs = np.sqrt(sum((np.abs(dp) ** 2 for dp in self.sensitivity.values()), np.zeros(params.size)))
        table["u_inputs"] = u_inputs
        table["u_c"] = np.hypot(u_fit, u_inputs)
        table["U95"] = COVERAGE_FACTOR * table["u_c"]
        table["dominant"] = _dominant(u_fit[None, :], {k: np.abs(v)[None, :] for k, v in self.sensitivity.items()})[0]
        return table

    def predict(self, amplitude_deg: ArrayLike, frequency_hz: ArrayLike) -> pd.DataFrame:
        """The map's stiffness (N·m/deg) and damping ratio (-) at the points, each with
        ``*_u_fit``, ``*_u_inputs``, ``*_u`` (combined), ``*_U95`` (k = 2) and ``*_dominant``."""
        a, f = np.broadcast_arrays(np.atleast_1d(np.asarray(amplitude_deg, float)),
                                   np.atleast_1d(np.asarray(frequency_hz, float)))
        params = _params(self.map)
        out = pd.DataFrame({"amplitude_deg": a, "frequency_hz": f})
        for name, fun in (("stiffness_nm_per_deg", _stiffness), ("damping_ratio", _damping)):
            value, u_fit = propagate(lambda p: fun(self.map, p, a, f), params, self.covariance)
            # first order along each input's Δp (its prediction is curved over a full Δp: a loose decay exponent)
            shares = {k: np.abs(fun(self.map, params + STEP * dp, a, f) - fun(self.map, params - STEP * dp, a, f))
                      / (2 * STEP) for k, dp in self.sensitivity.items()}
            u_inputs = np.sqrt(sum((s ** 2 for s in shares.values()), np.zeros(a.size)))
            out[name] = value
            out[f"{name}_u_fit"] = u_fit
            out[f"{name}_u_inputs"] = u_inputs
            out[f"{name}_u"] = np.hypot(u_fit, u_inputs)
            out[f"{name}_U95"] = COVERAGE_FACTOR * out[f"{name}_u"]
            out[f"{name}_dominant"] = _dominant(u_fit[:, None], {k: s[:, None] for k, s in shares.items()})[:, 0] \
                if a.size else []
        return out


def _params(m) -> np.ndarray:
    return np.concatenate([m.stiffness_params, m.ratio_params])


def _split(m, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    n = m.form.stiffness.size
    return p[:n], p[n:]


def _stiffness(m, p, a, f):
    return m.form.stiffness.value(_split(m, p)[0], a, f)


def _damping(m, p, a, f):
    ps, pr = _split(m, p)
    return m.form.stiffness.value(ps, a, f) / m.form.ratio.value(pr, a, f)


def _dominant(u_fit: np.ndarray, shares: dict[str, np.ndarray]) -> np.ndarray:
    names = [FIT, *shares]
    stack = np.stack([u_fit, *shares.values()])
    return np.asarray(names, dtype=object)[np.argmax(stack, axis=0)]


def _residuals(eq, stiffness: bool, p, a, f, target):
    from droptower.maps.solve import relative_residuals

    return relative_residuals(eq, stiffness, a, f, target)


def _gradient(eq, stiffness: bool, p, a, f, target) -> np.ndarray:
    """The gradient Jᵀr of the map's least squares (half the sum of squared relative residuals)."""
    res, jac = _residuals(eq, stiffness, p, a, f, target)
    return jac(p).T @ res(p)


def _hessian_inverse(eq, stiffness: bool, p, a, f, target, free: np.ndarray) -> np.ndarray:
    """(∂(Jᵀr)/∂p)⁺ over the free coefficients: the full Hessian JᵀJ + Σ rᵢ∇²rᵢ (central
    differences of the analytic gradient), not Gauss-Newton's JᵀJ alone, which misses the
    curvature of a loosely determined decay exponent when the residuals are not small."""
    idx = np.flatnonzero(free)
    h = np.zeros((p.size, p.size))
    for i in idx:
        step = 1e-6 * max(abs(p[i]), 1e-6)
        e = np.zeros(p.size)
        e[i] = step
        h[:, i] = (_gradient(eq, stiffness, p + e, a, f, target) - _gradient(eq, stiffness, p - e, a, f, target)) / (2 * step)
    out = np.zeros((p.size, p.size))
    sub = h[np.ix_(idx, idx)]
    out[np.ix_(idx, idx)] = np.linalg.pinv(0.5 * (sub + sub.T), rcond=1e-15)
    return out


def _cov_and_pinv(eq, stiffness: bool, p, a, f, target, free: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The fit's covariance s²(JᵀJ)⁺ and J⁺ of one equation over its free coefficients (those on
    a bound stay there; the map's own s²(JᵀJ)⁻¹, droptower.maps.solve); unidentified directions
    get no share (pinv)."""
    res, jac = _residuals(eq, stiffness, p, a, f, target)
    r, jm = res(p), jac(p)[:, free]
    s2 = float(r @ r) / max(r.size - int(free.sum()), 1)
    pinv = np.linalg.pinv(jm, rcond=1e-10)
    cov = np.zeros((p.size, p.size))
    cov[np.ix_(free, free)] = s2 * pinv @ pinv.T
    full = np.zeros((p.size, r.size))
    full[free] = pinv
    return cov, full


def map_uncertainty(results: pd.DataFrame | str | Path, uncertainty: RigUncertainty | None = None, *,
                    form: object = "paper", map_fit: object = None) -> MapUncertainty:
    """The map of ``results`` with the uncertainty of its coefficients and predictions.

    Parameters
    ----------
    results : DataFrame, str or Path
        The results table (as :func:`droptower.maps.fit_map` takes it); with input
        uncertainties of the lever inertia, an ``inertia_kgm2`` column (kg·m²: which fixture).
    uncertainty : RigUncertainty, optional
        The rig's input uncertainties (a rig file's ``[uncertainty]``, or
        :func:`~droptower.rig.uncertainty.override_uncertainty`); None: the fit's share only.
    form : str or MapForm
        The map's form, as :func:`~droptower.maps.fit_map` takes it.
    map_fit : MapFit, optional
        The map already fitted to ``results`` (else it is fitted here).

    Returns
    -------
    MapUncertainty
        Coefficients and predictions with u_fit, each correlated input's share, u_c and U95.
    """
    from droptower.maps import fit_map, read_results, select_tests

    if not isinstance(results, pd.DataFrame):
        results = read_results(results)
    m = map_fit if map_fit is not None else fit_map(results, form=form)
    usable, _ = select_tests(results, m.source)
    a, f, c, d = (usable[col].to_numpy(float) for col in ("amplitude_deg", "frequency_hz", "stiffness_nm_per_deg",
                                                          "damping_ratio"))
    ps, pr = m.stiffness_params, m.ratio_params
    names = [*m.form.stiffness_names, *m.form.ratio_names]
    free_s = np.array([n not in m.at_bounds for n in m.form.stiffness_names])
    free_r = np.array([n not in m.at_bounds for n in m.form.ratio_names])
    # the c/d equation is fitted to the stiffness equation's c over the measured d (droptower.maps.select)
    ratio_target = m.form.stiffness.value(ps, a, f) / d
    cov_s, _ = _cov_and_pinv(m.form.stiffness, True, ps, a, f, c, free_s)
    cov_r, _ = _cov_and_pinv(m.form.ratio, False, pr, a, f, ratio_target, free_r)
    hinv_s = _hessian_inverse(m.form.stiffness, True, ps, a, f, c, free_s)
    hinv_r = _hessian_inverse(m.form.ratio, False, pr, a, f, ratio_target, free_r)
    cov = np.zeros((len(names), len(names)))
    cov[:ps.size, :ps.size], cov[ps.size:, ps.size:] = cov_s, cov_r

    u = uncertainty or RigUncertainty()
    # each correlated input: (its name, the relative standard uncertainty, which drops, how it scales them)
    moves: list[tuple[str, float, np.ndarray, str]] = []
    not_given: list[str] = []
    everyone = np.ones(a.size, bool)
    if "inertia_kgm2" in usable.columns:
        inertias = usable["inertia_kgm2"].to_numpy(float)
        for j in sorted(set(inertias[np.isfinite(inertias)])):
            entry = u.inertia(j)
            if entry is None:
                not_given.append(f"inertia_kgm2@{j:g}")
            else:
                moves.append((f"inertia_kgm2@{j:g}", entry.standard / j, np.isclose(inertias, j, rtol=1e-6), "J"))
    elif u.inertias_kgm2:
        raise DroptowerError("the results have no inertia_kgm2 column: which fixture each test used is needed "
                             "for the inertias' uncertainty")
    else:
        not_given.append("inertia_kgm2")
    if u.sample_rate_hz is not None:
        rates = usable["sample_rate_hz"].to_numpy(float) if "sample_rate_hz" in usable.columns else None
        if rates is None or not np.all(np.isfinite(rates) & (rates > 0)):
            raise DroptowerError("the results have no sample_rate_hz column: its uncertainty needs the nominal rate")
        moves.append(("sample_rate_hz", float(np.median(u.sample_rate_hz.standard / rates)), everyone, "clock"))
    else:
        not_given.append("sample_rate_hz")
    if u.laser_radius_m is not None:
        radius = usable["sensor_radius_m"].to_numpy(float) if "sensor_radius_m" in usable.columns else None
        if radius is None or not np.all(np.isfinite(radius) & (radius > 0)):
            raise DroptowerError("the results have no sensor_radius_m column: the laser radius's uncertainty needs "
                                 "the nominal radius")
        moves.append(("laser_radius_m", float(np.median(u.laser_radius_m.standard / radius)), everyone, "laser"))
    else:
        not_given.append("laser_radius_m")
    if u.laser_calibration_rel is not None:
        moves.append(("laser_calibration_rel", u.laser_calibration_rel.standard, everyone, "laser"))
    else:
        not_given.append("laser_calibration_rel")

    sens: dict[str, np.ndarray] = {}
    for name, rel, which, kind in moves:
        grads = []
        for sign in (1.0, -1.0):
            e = sign * STEP * rel * which    # a small share of u: the first-order sensitivity, then per u
            a2, f2, c2 = a.copy(), f.copy(), c.copy()
            if kind == "J":            # c = J(ω² + δ²) of its fixture's drops; c/d alike, d unchanged
                c2 = c * (1 + e)
            elif kind == "clock":      # ω, δ ∝ f_s: f ∝ f_s, c ∝ f_s², d (δ/ω) unchanged
                f2, c2 = f * (1 + e), c * (1 + e) ** 2
            else:                      # the angle ∝ 1/(r·κ_L): the amplitude read too large by 1/(1 + e)
                a2 = a / (1 + e)
            grads.append((a2, f2, c2))
        # the minimiser's sensitivity (implicit function theorem): Δp = −H⁻¹·Δ(Jᵀr)
        dps = -hinv_s @ (_gradient(m.form.stiffness, True, ps, *grads[0]) -
                         _gradient(m.form.stiffness, True, ps, *grads[1])) / 2
        # the c/d equation's target moves with the stiffness map it is built on
        (ap, fp, _), (am, fm, _) = grads
        tp, tm = m.form.stiffness.value(ps + dps, ap, fp) / d, m.form.stiffness.value(ps - dps, am, fm) / d
        dpr = -hinv_r @ (_gradient(m.form.ratio, False, pr, ap, fp, tp) - _gradient(m.form.ratio, False, pr, am, fm, tm)) / 2
        sens[name] = np.concatenate([dps, dpr]) / STEP     # Δp per +1 u of the input (first order)
    return MapUncertainty(m, cov, sens, tuple(not_given), tuple(names))
