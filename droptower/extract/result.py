"""The result of one extraction: SI fields, and a flat output dict whose names carry units."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from droptower.damped_cosine import DecayFit, TorqueFit

DEG = math.pi / 180.0

#: output name -> (SI field, factor: output = SI value * factor). Fields with an entry in
#: ``ExtractionResult.std`` also get ``<output name>_std``.
OUTPUTS: dict[str, tuple[str, float]] = {
    "frequency_hz": ("frequency_hz", 1.0),
    "angular_frequency_rad_per_s": ("omega_rad_per_s", 1.0),
    "decay_coefficient_per_s": ("delta_per_s", 1.0),
    "amplitude_deg": ("amplitude_ref_rad", 1.0 / DEG),
    "initial_amplitude_deg": ("amplitude_rad", 1.0 / DEG),
    "phase_rad": ("phase_rad", 1.0),
    "stiffness_nm_per_rad": ("stiffness_nm_per_rad", 1.0),
    "stiffness_nm_per_deg": ("stiffness_nm_per_rad", DEG),
    "damping_ratio": ("damping_ratio", 1.0),  # Rapp's d = E_diss/E_el, not Lehr's D (docs/theory.md#damping-measures)
    "lehr_damping": ("lehr_damping", 1.0),
    "stiffness_torque_nm_per_rad": ("stiffness_torque_nm_per_rad", 1.0),
    "stiffness_torque_nm_per_deg": ("stiffness_torque_nm_per_rad", DEG),
    "stiffness_m2_m1_deviation_pct": ("stiffness_deviation", 100.0),
    "loss_factor": ("loss_factor", 1.0),
    "relative_damping_psi": ("relative_damping_psi", 1.0),
    "torque_amplitude_nm": ("torque_amplitude_nm", 1.0),
    "torque_phase_rad": ("torque_phase_rad", 1.0),
    "torque_fit_offset_nm": ("torque_fit_offset_nm", 1.0),
    "fit_error": ("fit_error", 1.0),
    "torque_fit_error": ("torque_fit_error", 1.0),
    "impact_onset_time_s": ("impact_time_s", 1.0),
    "window_start_s": ("window_start_s", 1.0),
    "window_end_s": ("window_end_s", 1.0),
    "samples_per_period": ("samples_per_period", 1.0),
    "sample_rate_hz": ("sample_rate_hz", 1.0),
    "angle_offset_deg": ("angle_offset_rad", 1.0 / DEG),
    "torque_offset_nm": ("torque_offset_nm", 1.0),
    "impact_impulse_n_s": ("impact_impulse_ns", 1.0),
    "lever_rate_after_rad_per_s": ("lever_rate_after_rad_per_s", 1.0),
    "decay_fit_initial_rate_rad_per_s": ("decay_fit_initial_rate_rad_per_s", 1.0),
    "impact_energy_j": ("impact_energy_j", 1.0),
    "second_impact_after_s": ("second_impact_after_s", 1.0),
    "inertia_kgm2": ("inertia_kgm2", 1.0),
}


#: outputs that are text, not numbers (besides ``flags``)
TEXT_OUTPUTS = ("lever_rate_after_from",)


@dataclass
class ExtractionResult:
    """Stiffness and damping of one drop test, SI units (Rapp et al. 2022, eq. 13-18, docs/theory.md#extraction).

    Decay fit: amplitude_rad φ̂ (at the impact), delta_per_s δ, omega_rad_per_s ω, phase_rad Φ;
    frequency_hz f = ω/2π; amplitude_ref_rad φ̂_ref (eq. 18, middle of the window);
    stiffness_nm_per_rad c_dyn,M1 = J(ω² + δ²) (eq. 15); damping_ratio Rapp's d = E_diss/E_el = ½(e^(4πδ/ω) − 1) (eq. 16;
    not Lehr's D: that is the property ``lehr_damping``);
    stiffness_torque_nm_per_rad c_dyn,M2 = T(φ_max)/φ_max (eq. 17), stiffness_deviation M2/M1 − 1;
    loss_factor η and relative_damping_psi ψ: servo-comparable (docs/theory.md#damping-measures), the values a
    servo bench would measure on the linear Kelvin–Voigt coupling with this decay.
    fit_error: RMS residual / peak of the fitted angle over the window (torque_fit_error the same
    for the torque). Times: impact_time_s (output ``impact_onset_time_s``: where the force pulse, else the
    angle, starts) on the log's clock; window_start_s, window_end_s and
    second_impact_after_s (first later contact, NaN if none) since the impact. double_impact:
    a second contact within the first period (docs/theory.md#decay) or the fit window. angle_offset_rad, torque_offset_nm: pre-trigger
    means (sensor offsets and preload). Impact (independent of the window): lever_rate_after_rad_per_s
    φ'(0+) from the force impulse, L·∫F dt / J, else from the impact law on the log's drop mass,
    height and restitution (lever_rate_after_from: ``"impact_force"``, ``"impact_law"`` or ``""``
    with NaN), impact_energy_j ½·J·φ'(0+)²; decay_fit_initial_rate_rad_per_s |φ'(0)| of the decay
    fitted over the window (it changes with the window). std: standard uncertainties of the SI fields by name.
    geometry: the geometry cross-checks (:func:`droptower.extract.geometry.geometry_checks`:
    ``amplitude_laser_torque_deviation_pct``, ``impact_energy_law_j``, ``impact_energy_decay_j``,
    ``impact_energy_deviation_pct``), filled by :func:`droptower.extract.extract_drops`.
    NaN where a value cannot be computed (no torque or force channel, no lever length).
    """

    frequency_hz: float
    omega_rad_per_s: float
    delta_per_s: float
    amplitude_rad: float
    amplitude_ref_rad: float
    phase_rad: float
    stiffness_nm_per_rad: float
    damping_ratio: float
    stiffness_torque_nm_per_rad: float
    stiffness_deviation: float
    loss_factor: float
    relative_damping_psi: float
    torque_amplitude_nm: float
    torque_phase_rad: float
    torque_fit_offset_nm: float
    fit_error: float
    torque_fit_error: float
    impact_time_s: float
    window_start_s: float
    window_end_s: float
    samples_per_period: float
    sample_rate_hz: float
    angle_offset_rad: float
    torque_offset_nm: float
    impact_impulse_ns: float
    decay_fit_initial_rate_rad_per_s: float
    lever_rate_after_rad_per_s: float
    lever_rate_after_from: str
    impact_energy_j: float
    second_impact_after_s: float
    inertia_kgm2: float
    double_impact: bool
    flags: tuple[str, ...]
    std: dict[str, float] = field(default_factory=dict)
    geometry: dict[str, float] = field(default_factory=dict)
    angle_fit: DecayFit | None = field(default=None, repr=False)
    torque_fit: TorqueFit | None = field(default=None, repr=False)

    @property
    def lehr_damping(self) -> float:
        """Lehr's D (ζ) of the fitted decay, r/√(1 + r²) with r = δ/ω (docs/theory.md#damping-measures)."""
        from droptower.sdof import lehr_damping

        return float(lehr_damping(self.delta_per_s, self.omega_rad_per_s))

    def as_dict(self) -> dict[str, Any]:
        """Deprecated: :meth:`to_dict` (removed in the next release)."""
        from droptower.deprecation import warn_deprecated

        warn_deprecated("ExtractionResult.as_dict()", "ExtractionResult.to_dict()")
        return self.to_dict()

    def to_dict(self) -> dict[str, Any]:
        """Flat dict for tables and JSON: unit-suffixed names, ``<name>_std`` uncertainties,
        ``double_impact`` (bool) and ``flags`` (list of flag names)."""
        out: dict[str, Any] = {}
        for name, (attr, factor) in OUTPUTS.items():
            out[name] = float(getattr(self, attr)) * factor
            if attr in self.std:
                out[f"{name}_std"] = float(self.std[attr]) * abs(factor)
        out.update(self.geometry)
        out["lever_rate_after_from"] = self.lever_rate_after_from
        out["double_impact"] = bool(self.double_impact)
        out["flags"] = list(self.flags)
        return out
