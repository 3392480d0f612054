"""Rapp et al.'s (2022) characteristic map as a model (eq. 19-20): family and strategy.

The first-harmonic stiffness and damping of every steady block mapped with eq. 19-20; the
model is a Kelvin-Voigt coupling following the map.
"""
from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from droptower.errors import DroptowerError
from droptower.identify.cycles import evaluate_block, local_amplitude_frequency
from droptower.identify.data import Segment
from droptower.identify.families.base import Family, stiffness_parameter
from droptower.identify.families.stages import Setup, steady_blocks
from droptower.identify.fit import FitResult, FitVariable
from droptower.identify.result import Identification, metrics
from droptower.identify.result import Parameters

class OverlayFamily(Family):
    """Rapp et al.'s (2022) characteristic map as a model: a linear Kelvin-Voigt coupling (spring k,
    dashpot c) whose k and c follow the map at each cycle's amplitude and frequency.

    The parameter vector is one (k, c) pair; the map is identified by the strategy.
    """

    kind = "overlay"
    title = "characteristic-map overlay: Kelvin-Voigt with map stiffness and damping"
    source = "Rapp et al. 2022 (drop-tower characteristic map), eq. 19-20"
    OPTIONS = {"amplitude_deg": 0.0, "frequency_hz": 0.0}

    def _parameters(self):
        s = self.scale
        return [stiffness_parameter("k_nm_per_rad", s), FitVariable("c_nms_per_rad", 1e-9 * s.stiffness_nm_per_rad,
                                                         1e3 * s.stiffness_nm_per_rad)]

    def guess(self):
        s = self.scale
        return np.array([s.stiffness_nm_per_rad, 0.1 * s.stiffness_nm_per_rad / (2 * np.pi * max(s.frequency_hz, 1e-3))])

    def elements(self, v):
        k, c = v
        return [{"kind": "spring", "stiffness": k}, {"kind": "dashpot", "damping": c}]


def kelvin_voigt_from_map(fitted: Any, amplitude_deg: np.ndarray, frequency_hz: np.ndarray
                          ) -> tuple[np.ndarray, np.ndarray]:
    """Spring (N*m/rad) and dashpot (N*m*s/rad) of the Kelvin-Voigt coupling that has the map's
    stiffness and damping ratio at (amplitude, frequency), clipped into the measured range.

    The map's damping ratio is the drop tower's d = E_diss / E_el; the Kelvin-Voigt coupling
    with that d swinging at its damped frequency has r = delta / omega = ln(1 + 2 d) / (4 pi)
    and loss factor eta = 2 r / (1 + r^2) (docs/theory.md#extraction, #damping-measures), so c = eta k / Omega.
    """
    r = fitted.range
    a = np.clip(amplitude_deg, r.amplitude_deg_min, r.amplitude_deg_max)
    f = np.clip(frequency_hz, r.frequency_hz_min, r.frequency_hz_max)
    k = np.degrees(1.0) * fitted.stiffness_nm_per_deg(a, f)  # N*m/deg -> N*m/rad
    ratio = np.log1p(2.0 * np.maximum(fitted.damping_ratio(a, f), 0.0)) / (4.0 * np.pi)
    eta = 2.0 * ratio / (1.0 + ratio ** 2)
    return k, eta * k / (2.0 * np.pi * f)


def identify_overlay(s: Setup, segments: list[Segment], start: float, **_) -> Identification:
    """Rapp et al.'s (2022) map as a model. Every steady sine block is evaluated like a servo test
    (K', loss factor); the map (eq. 19 for the stiffness K', eq. 20 for the drop-tower damping
    ratio equivalent to the loss factor, :func:`droptower.servo.drop_tower_equivalent_damping_ratio`)
    is fitted with :func:`droptower.maps.fitting.fit_map`. The model's torque is k theta + c dtheta/dt
    with k, c from the map at the amplitude and frequency of the half cycle each sample lies in
    (the same as the core's spring + dashpot, which have no memory). Limits: a Kelvin-Voigt
    coupling has one stiffness for the mean load and the oscillation (a preload is carried at
    the dynamic stiffness), elliptic loops only, no relaxation, no amplitude memory; outside
    the measured amplitude/frequency range the map is held at its edge."""
    import pandas as pd

    from droptower.maps.fitting import fit_map
    from droptower.servo import drop_tower_equivalent_damping_ratio

    fam: OverlayFamily = s.family  # type: ignore[assignment]
    rows = []
    for sb in steady_blocks(segments):
        seg = segments[sb.segment]
        ev = evaluate_block(seg.measured_angle, seg.measured_torque, seg.dt_s, sb.block)
        if ev is not None and ev.storage_stiffness_nm_per_rad > 0:
            eta = ev.loss_stiffness_nm_per_rad / ev.storage_stiffness_nm_per_rad
            rows.append({"file": sb.window.name, "amplitude_deg": math.degrees(ev.angle_amplitude_rad),
                         "frequency_hz": ev.frequency_hz,
                         "stiffness_nm_per_deg": ev.storage_stiffness_nm_per_rad * math.pi / 180.0,
                         "damping_ratio": float(drop_tower_equivalent_damping_ratio(eta))})
    table = pd.DataFrame(rows, columns=["file", "amplitude_deg", "frequency_hz", "stiffness_nm_per_deg",
                                        "damping_ratio"])
    try:
        fitted = fit_map(table, source="steady sine blocks")
    except DroptowerError as exc:
        raise DroptowerError(f"model overlay needs steady sine blocks at several amplitudes and frequencies; "
                             f"{len(rows)} found: {exc.problem}") from None

    def predict(segs: list[Segment]) -> list[np.ndarray]:
        out = []
        for seg in segs:
            amp, freq = local_amplitude_frequency(seg.angle_rad, seg.dt_s)
            k, c = kelvin_voigt_from_map(fitted, np.degrees(amp), freq)
            rate = np.diff(seg.angle_rad, prepend=0.0) / seg.dt_s  # the core's dashpot: rate of the step
            out.append(k * seg.angle_rad + c * rate)
        return out

    fit_metrics = metrics(segments, predict(segments))
    amp_out = float(fam.options["amplitude_deg"]) or float(table["amplitude_deg"].median())
    f_out = float(fam.options["frequency_hz"]) or float(table["frequency_hz"].median())
    k_out, c_out = (float(v) for v in kelvin_voigt_from_map(fitted, np.array(amp_out), np.array(f_out)))
    v_out = np.array([k_out, c_out])
    stage = FitResult("map (Rapp et al. 2022, eq. 19-20) by droptower.maps.fit_map", fam.names, v_out,
                      np.ones(2, bool), np.full(2, np.nan), list(fitted.at_bounds), fit_metrics, 0, 0, 0, 0,
                      time.perf_counter() - start, True, "map fitted")
    names = [f"{k}_{u}" for k, u in zip(fitted.coefficients, _map_units())]
    result = Identification(
        fam.kind, Parameters.estimates(dict(zip(names, fitted.coefficients.values())),
                                       dict(zip(names, fitted.uncertainties.values()))),
        [f"{k}_{u}" for k, u in zip(fitted.coefficients, _map_units()) if k in fitted.at_bounds],
        fit_metrics, fam.coupling(v_out, description=f"{fam.title}; Kelvin-Voigt at {amp_out:.4g} deg, {f_out:.4g} Hz"),
        stages=[stage], predict=predict, derived={"k_nm_per_rad": k_out, "c_nms_per_rad": c_out},
        coupling_note=(f"a Kelvin-Voigt coupling with the map's stiffness and damping at amplitude {amp_out:.4g} deg "
                       f"and frequency {f_out:.4g} Hz (map range {fitted.range.amplitude_deg_min:.3g}-"
                       f"{fitted.range.amplitude_deg_max:.3g} deg, {fitted.range.frequency_hz_min:.3g}-"
                       f"{fitted.range.frequency_hz_max:.3g} Hz)"),
        extra={"map": fitted.to_dict(), "blocks": rows,
               "written_at": {"amplitude_deg": amp_out, "frequency_hz": f_out}})
    return result


def _map_units() -> list[str]:
    from droptower.maps.mapfit import UNITS

    return list(UNITS.values())


FAMILY = OverlayFamily
strategy = identify_overlay
