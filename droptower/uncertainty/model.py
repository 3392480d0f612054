"""The measurement model of one drop (GUM 4.1.1, Y = f(X_1, ..., X_N)): the extraction's own
closed forms (Rapp et al. 2022, eq. 15-18; docs/theory.md#extraction) evaluated on the fitted
decay, with the rig's inputs at their true values instead of the nominal ones.

The fit's parameters θ = (φ̂, δ, ω, Φ, a, b, offset) carry the fit's covariance (the Jacobian's
s²(JᵀJ)⁻¹, docs/theory.md#extraction); the inputs enter where the extraction took them as known:

- the sample clock: a log labelled at the nominal rate f_s,0 whose clock ran at f_s shows
  ω_true = ω·f_s/f_s,0 and δ_true = δ·f_s/f_s,0 (the window's length scales inversely);
- the lever inertia: c = J(ω² + δ²) (eq. 15) with the true J;
- the laser: the angle arctan(s/r) read through the nominal radius r_0 and a calibration factor
  κ_L (reading / true): φ_true ≈ φ·r_0/(r·κ_L) at small angles, so amplitudes carry u_r/r and
  u_κ, frequency and damping do not;
- the torque flange: T_true = T/κ_T; c_M2 = T(φ_max)/φ_max carries κ_T and the laser's factor;
- the impact energy ½·J·φ'(0+)²: from the force impulse, φ'(0+) = L·∫F dt/(κ_F·J), so
  E = ½(L·∫F dt/κ_F)²/J; from the impact law (docs/theory.md#impact) on m, h, the restitution
  and J, L. The impulse's own noise is not estimated (no fit term); the restitution is taken as known.

Every function here is vectorised over trials: θ has shape (7, N) and each input (N,).
"""
from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from droptower.errors import DroptowerError
from droptower.extract.extractor import _derived
from droptower.extract.result import ExtractionResult
from droptower.units import GRAVITY_M_PER_S2

#: the per-drop quantities (SI fields of :class:`~droptower.extract.ExtractionResult`) the model gives
QUANTITIES: tuple[str, ...] = ("frequency_hz", "stiffness_nm_per_rad", "damping_ratio", "loss_factor",
                               "amplitude_ref_rad", "impact_energy_j", "stiffness_torque_nm_per_rad",
                               "torque_amplitude_nm")

_FROM_DERIVED = {"frequency_hz": 0, "amplitude_ref_rad": 4, "stiffness_nm_per_rad": 5, "damping_ratio": 6,
                 "loss_factor": 7, "stiffness_torque_nm_per_rad": 9, "torque_amplitude_nm": 11}


@dataclass(frozen=True)
class DropModel:
    """One drop's measurement model: the fitted θ and its covariance, the window, and the nominal
    values the extraction used. Build it with :meth:`from_result`."""

    theta: np.ndarray              # (7,): φ̂ rad, δ 1/s, ω rad/s, Φ rad, a, b, offset N·m
    cov: np.ndarray                # (7, 7): the angle fit's and the torque fit's covariances
    window_s: float                # the fit window's end since the impact (s, the log's clock)
    window_start_s: float
    has_torque: bool
    nominal: dict[str, float]      # the nominal value of each input the extraction used
    energy_route: str              # "impact_force", "impact_law" or "" (as the result's lever_rate_after_from)
    impulse_ns: float
    restitution: float
    gravity_m_per_s2: float

    @classmethod
    def from_result(cls, result: ExtractionResult, *, lever_length_m: float | None = None,
                    laser_radius_m: float | None = None, drop_mass_kg: float | None = None,
                    drop_height_m: float | None = None, restitution: float | None = None,
                    gravity_m_per_s2: float = GRAVITY_M_PER_S2) -> "DropModel":
        """The model of an extraction (it must keep its fits: ``result.angle_fit``).

        The nominal values are those the extraction used: J and the sample rate from ``result``,
        the rest as given (m, m, kg, m; restitution for the impact-law energy). For the energy
        from the force impulse the lever length is the one the extraction used, L = J·φ'(0+)/∫F dt.
        """
        if not isinstance(result, ExtractionResult):
            raise TypeError(f"DropModel.from_result: expects an ExtractionResult, got {type(result).__name__}")
        if result.angle_fit is None:
            raise DroptowerError("the extraction result carries no angle fit (result.angle_fit is None)",
                                 where="result")
        theta = np.concatenate([result.angle_fit.params,
                                result.torque_fit.params if result.torque_fit is not None else np.zeros(3)])
        cov = np.zeros((7, 7))
        cov[:4, :4] = result.angle_fit.cov
        if result.torque_fit is not None:
            cov[4:, 4:] = result.torque_fit.cov  # independent fits, as the extractor treats them
        route = result.lever_rate_after_from
        if route == "impact_force":  # the lever length the extraction used: φ'(0+) = L·∫F dt / J
            lever_length_m = result.inertia_kgm2 * result.lever_rate_after_rad_per_s / result.impact_impulse_ns
        if route == "impact_law" and None in (lever_length_m, drop_mass_kg, drop_height_m, restitution):
            raise DroptowerError("the impact energy came from the impact law: give the drop's lever_length_m, "
                                 "drop_mass_kg, drop_height_m and restitution (the log's metadata has them)", where="result")
        nominal = {"inertia_kgm2": result.inertia_kgm2, "sample_rate_hz": result.sample_rate_hz,
                   "lever_length_m": lever_length_m, "laser_radius_m": laser_radius_m, "drop_mass_kg": drop_mass_kg,
                   "drop_height_m": drop_height_m, "torque_calibration_rel": 1.0, "laser_calibration_rel": 1.0,
                   "force_calibration_rel": 1.0}
        return cls(theta=theta, cov=cov, window_s=result.window_end_s, window_start_s=result.window_start_s,
                   has_torque=result.torque_fit is not None,
                   nominal={k: float(v) for k, v in nominal.items() if v is not None},
                   energy_route=route, impulse_ns=float(result.impact_impulse_ns),
                   restitution=float(restitution) if restitution is not None else math.nan,
                   gravity_m_per_s2=float(gravity_m_per_s2))

    def evaluate(self, theta: np.ndarray, inputs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Every quantity of :data:`QUANTITIES` (SI, shape (N,)) for fit parameters ``theta``
        (7, N) or (7,) and the true values ``inputs`` (name -> (N,) or scalar); an input left out
        stands at its nominal value."""
        theta = np.asarray(theta, float)
        if theta.ndim == 1:
            theta = theta[:, None]
        n = max([theta.shape[1], *(np.size(v) for v in inputs.values())])
        theta = np.broadcast_to(theta, (7, n))

        def ratio(name: str) -> np.ndarray | float:
            return np.asarray(inputs[name], float) / self.nominal[name] if name in inputs else 1.0

        def value(name: str) -> np.ndarray | float:
            return np.asarray(inputs[name], float) if name in inputs else self.nominal.get(name, math.nan)

        clock = ratio("sample_rate_hz")
        scaled = theta.copy()
        scaled[1] = theta[1] * clock
        scaled[2] = theta[2] * clock
        inertia = value("inertia_kgm2")
        shape = (n,)
        derived = _derived(scaled, inertia, self.window_s / clock, self.window_start_s / clock, self.has_torque)
        out = {name: np.broadcast_to(np.asarray(derived[i], float), shape).copy()
               for name, i in _FROM_DERIVED.items()}
        # the laser: φ_true = φ·r_0/(r·κ_L) (small angles; arctan(s/r) ≈ s/r)
        angle = ratio("laser_radius_m") * value("laser_calibration_rel")
        torque = value("torque_calibration_rel")
        out["amplitude_ref_rad"] = out["amplitude_ref_rad"] / angle
        out["torque_amplitude_nm"] = out["torque_amplitude_nm"] / torque
        out["stiffness_torque_nm_per_rad"] = out["stiffness_torque_nm_per_rad"] * angle / torque
        out["impact_energy_j"] = np.broadcast_to(self._energy(inputs, value), shape).astype(float)
        return out

    def _energy(self, inputs: dict[str, np.ndarray], value) -> np.ndarray:
        inertia, lever = value("inertia_kgm2"), value("lever_length_m")
        if self.energy_route == "impact_force":
            # J·φ'(0+) = L·∫F dt (Rapp et al. 2022, "Theory of Impact Investigation"), impulse read through κ_F
            return 0.5 * (lever * self.impulse_ns / value("force_calibration_rel")) ** 2 / inertia
        if self.energy_route == "impact_law":
            from droptower.rig.impact_law import impact_velocities  # the rig package imports pymunk

            return impact_velocities(value("drop_mass_kg"), inertia, lever, value("drop_height_m"), self.restitution,
                                     self.gravity_m_per_s2).impact_energy_j
        return np.asarray(math.nan)

    def check_inputs(self, given: Iterable[str]) -> None:
        """Refuse inputs whose nominal value the model does not hold (one-line DroptowerError)."""
        missing = [name for name in given if name not in self.nominal]
        if missing:
            raise DroptowerError(f"the model holds no nominal value of {', '.join(missing)}: give it to "
                                 "DropModel.from_result", where=missing[0])

    def nominal_values(self) -> dict[str, float]:
        """The quantities at the fitted θ and the nominal inputs (what the extraction reported)."""
        return {k: float(v[0]) for k, v in self.evaluate(self.theta, {}).items()}
