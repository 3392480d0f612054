"""Predict a test plan before running it: amplitudes, frequencies, torques, double impacts.

For every distinct test condition: the impact law (NOTES §1.2) gives the lever's rate after
the impact; a free decay of the lever on the *nonlinear* coupling, preload twist included,
gives the first period, peaks, decay and peak torque; the drop mass's free flight against the
lever tip's path gives the double-impact check of seed 004 (NOTES §1.3: a second impact
within the first oscillation period). All conditions advance together through the coupling's
batch axis (one :meth:`Coupling.step` per step), integrated exactly like the pymunk scene
(symplectic Euler at the rig's internal step), so plan and simulation agree.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from droptower.errors import DroptowerError
from droptower.extract.decay import fit_decay, start_frequency_and_decay
from droptower.rheology import Coupling
from droptower.rig.config import RigConfig
from droptower.rig.impact import (drop_mass_path, first_period, impact_velocities,
                                  lever_tip_path, second_impact_time)
from droptower.rig.preload import Pretwist, pretwist
from droptower.sdof import damping_ratio

MIN_SAMPLES_PER_PERIOD = 20   # fewer samples per oscillation and the decay fit has too little to work with
MIN_RECORD_PERIODS = 0.75     # seed 004 / NOTES §1.4: at least three quarters of a period after the impact
CHUNK_STEPS = 1024
MAX_DECAY_S = 2.0             # give up looking for a first period after this long


@dataclass
class FreeDecay:
    """The lever's free decay after the impact: time_s (N,) from the impact; angle_rad (B, N)
    rotation from rest; torque_nm (B, N) coupling torque (preload included); period_s (B,)
    time of the angle's second zero crossing (NaN if it never came)."""

    time_s: np.ndarray
    angle_rad: np.ndarray
    torque_nm: np.ndarray
    period_s: np.ndarray


def free_decay(coupling: Coupling, inertia_kgm2: np.ndarray, rate0_rad_per_s: np.ndarray, twist: Pretwist,
               dt_s: float, min_duration_s: float = 0.0) -> FreeDecay:
    """Integrate J phi'' = T_screw - T_coupling(twist + phi) from phi = 0, phi' = rate0 (B,).

    Same scheme as the pymunk scene (the torque at the angle the step reaches, then the rate);
    runs until every condition has completed its first period plus a quarter and
    ``min_duration_s`` has passed (at most :data:`MAX_DECAY_S`).
    """
    J = np.asarray(inertia_kgm2, float)
    B = J.size
    state = twist.state.copy()
    screw = twist.torque_nm
    phi = np.zeros(B)
    rate = np.asarray(rate0_rad_per_s, float).copy()
    a_chunk = np.empty((B, CHUNK_STEPS))
    t_chunk = np.empty((B, CHUNK_STEPS))
    a_parts, t_parts = [np.zeros((B, 1))], [screw[:, None].copy()]
    n_max = int(math.ceil(MAX_DECAY_S / dt_s))
    while True:
        for j in range(CHUNK_STEPS):
            phi += rate * dt_s
            tq = coupling.step(state, twist.angle_rad + phi, dt_s)
            rate += (screw - tq) / J * dt_s
            a_chunk[:, j] = phi
            t_chunk[:, j] = tq
        a_parts.append(a_chunk.copy())
        t_parts.append(t_chunk.copy())
        angle = np.concatenate(a_parts, axis=1)
        time = np.arange(angle.shape[1]) * dt_s
        period = first_period(time, angle)
        done = np.all(np.isfinite(period)) and time[-1] >= max(min_duration_s, 1.25 * float(np.max(period)))
        if done or angle.shape[1] > n_max:
            break
    return FreeDecay(time_s=time, angle_rad=angle, torque_nm=np.concatenate(t_parts, axis=1), period_s=period)


def plan(rig: RigConfig, coupling: Coupling, conditions: pd.DataFrame, duration_s: float = 0.25) -> pd.DataFrame:
    """One row per condition (columns of :meth:`DOE.conditions`): predictions and warnings.

    duration_s: the record length after the impact (for the 3/4-period check).
    """
    cond = conditions.reset_index(drop=True)
    J = cond["inertia_kgm2"].to_numpy(float)
    m1 = cond["drop_mass_kg"].to_numpy(float)
    h = cond["drop_height_m"].to_numpy(float)
    preload = cond["preload_nm"].to_numpy(float) if "preload_nm" in cond else np.zeros(len(cond))
    L, g = rig.lever_length_m, rig.gravity_m_per_s2
    iv = impact_velocities(m1, J, L, h, rig.restitution, g)
    twist = pretwist(coupling, preload, rig.simulation.preload_ramp_s, rig.simulation.preload_hold_s)
    rig.check_time_step(coupling, J, twist.angle_rad, iv.impact_m_per_s)  # the decay is stepped like the scene
    decay = free_decay(coupling, J, iv.rate_after_rad_per_s, twist, rig.dt_s)
    t, a = decay.time_s, decay.angle_rad
    period = decay.period_s
    horizon = np.where(np.isfinite(period), period, t[-1])
    in_period = t[None, :] <= horizon[:, None]

    # peaks of the first cycle
    first = np.argmax(np.where(in_period, a, -np.inf), axis=1)
    second = np.argmin(np.where(in_period, a, np.inf), axis=1)
    rows = np.arange(len(cond))
    p1, p2 = a[rows, first], a[rows, second]
    t1, t2 = t[first], t[second]
    omega = 2.0 * np.pi / period
    with np.errstate(divide="ignore", invalid="ignore"):
        delta = np.where(p2 < 0, np.log(p1 / np.abs(p2)) / (t2 - t1), np.nan)
        envelope = p1 * np.exp(delta * t1) / np.sin(omega * t1)
    amplitude_ref = envelope * np.exp(-delta * period / 2.0)  # seed 004 eq. 18, window = first cycle
    peak_torque = np.max(np.where(in_period, np.abs(decay.torque_nm), 0.0), axis=1)

    # second impact: drop mass in free flight against the lever tip, within the first period
    x1 = drop_mass_path(iv.drop_mass_after_m_per_s[:, None], t[None, :], g)
    x2 = lever_tip_path(a, L)
    t_second = second_impact_time(t, x1, x2, horizon)
    after_peak = in_period & (t[None, :] >= t1[:, None])
    clearance = np.min(np.where(after_peak, x2 - x1, np.inf), axis=1)

    fs = rig.sensors.sample_rate_hz
    force_peak = np.pi * iv.impulse_ns / (2.0 * rig.sensors.impact_force.contact_duration_s)
    out = cond.copy()
    out["impact_velocity_m_per_s"] = iv.impact_m_per_s
    out["drop_mass_velocity_after_m_per_s"] = iv.drop_mass_after_m_per_s
    out["lever_tip_velocity_after_m_per_s"] = iv.lever_tip_after_m_per_s
    out["lever_rate_after_rad_per_s"] = iv.rate_after_rad_per_s
    out["impact_energy_j"] = iv.impact_energy_j
    out["impulse_n_s"] = iv.impulse_ns
    out["impact_force_peak_n"] = force_peak
    out["pretwist_deg"] = np.degrees(twist.angle_rad)
    out["amplitude_deg"] = np.degrees(p1)
    out["amplitude_ref_deg"] = np.degrees(amplitude_ref)
    out["max_twist_deg"] = np.degrees(np.abs(twist.angle_rad) + np.maximum(p1, np.abs(p2)))
    # frequency and decay as the extractor reads them (its fit over the first cycle, seed 004
    # eq. 13-16): for an amplitude-dependent loss the two-peak decrement differs from it
    # (each over its own first period and a quarter: a row's fit must not depend on the batch)
    fitted = np.array([_first_cycle_fit(t[t <= 1.25 * T], row[t <= 1.25 * T]) if np.isfinite(T) else (np.nan, np.nan)
                       for row, T in zip(a, period)])
    omega_fit = np.where(np.isfinite(fitted[:, 0]), fitted[:, 0], omega)
    delta_fit = np.where(np.isfinite(fitted[:, 1]), fitted[:, 1], delta)
    out["frequency_hz"] = omega_fit / (2.0 * np.pi)
    out["period_s"] = period
    out["decay_per_s"] = delta_fit
    out["damping_ratio"] = damping_ratio(delta_fit, omega_fit)
    out["peak_torque_nm"] = peak_torque
    out["double_impact"] = np.isfinite(t_second)
    out["second_impact_time_s"] = t_second
    out["min_clearance_mm"] = 1e3 * clearance
    out["samples_per_period"] = period * fs
    out["warnings"] = [_warnings(rig, row, duration_s) for row in out.itertuples(index=False)]
    return out


def _first_cycle_fit(t: np.ndarray, angle: np.ndarray) -> tuple[float, float]:
    """(omega rad/s, delta 1/s) of a damped sinusoid fitted to the decay's first cycle, as the
    extractor fits a log; (NaN, NaN) where the fit fails."""
    try:
        omega0, delta0 = start_frequency_and_decay(t, angle, 0.0)
        window = t <= 2.0 * np.pi / omega0
        _, delta, omega, _ = fit_decay(t[window], angle[window], omega0, delta0).params
        return float(omega), float(delta)
    except (DroptowerError, ValueError, np.linalg.LinAlgError):  # the two-peak estimate stands in
        return math.nan, math.nan


def _warnings(rig: RigConfig, r, duration_s: float) -> list[str]:
    w = []
    if not any(math.isclose(r.inertia_kgm2, j, rel_tol=1e-9) for j in rig.inertias_kgm2):
        w.append(f"inertia {r.inertia_kgm2:g} kg*m^2 is not a lever fixture of the rig")
    if not any(math.isclose(r.drop_mass_kg, m, rel_tol=1e-9) for m in rig.drop_masses_kg):
        w.append(f"drop mass {r.drop_mass_kg:g} kg is not one of the rig's")
    if math.isnan(r.period_s):
        w.append("no complete oscillation (overdamped?)")
    if r.max_twist_deg > rig.coupling_limit_deg:
        w.append(f"twist {r.max_twist_deg:.1f} deg > coupling limit {rig.coupling_limit_deg:g} deg")
    if r.peak_torque_nm > rig.sensors.torque.range_nm:
        w.append(f"torque {r.peak_torque_nm:.0f} N*m > sensor range {rig.sensors.torque.range_nm:g} N*m")
    if r.impact_force_peak_n > rig.sensors.impact_force.range_n:
        w.append(f"impact force {r.impact_force_peak_n:.0f} N > sensor range {rig.sensors.impact_force.range_n:g} N")
    if r.samples_per_period < MIN_SAMPLES_PER_PERIOD:
        w.append(f"only {r.samples_per_period:.0f} samples per period (< {MIN_SAMPLES_PER_PERIOD})")
    if duration_s < MIN_RECORD_PERIODS * r.period_s:
        w.append(f"record {duration_s:g} s shorter than 3/4 period ({r.period_s:.3g} s)")
    if r.double_impact:
        w.append(f"double impact at {1e3 * r.second_impact_time_s:.1f} ms (period {1e3 * r.period_s:.1f} ms)")
    return w
