"""Predict a test plan before running it: amplitudes, frequencies, torques, double impacts.

For every distinct test condition: the impact law (docs/theory.md#impact) gives the lever's rate after
the impact; a free decay of the lever on the *nonlinear* coupling, preload twist included,
gives the first period, peaks, decay and peak torque; the drop mass's free flight against the
lever tip's path gives the double-impact check of Rapp et al. 2022 (docs/theory.md#double-impact: a second impact
within the first oscillation period). All conditions advance together through the coupling's
batch axis, integrated by :mod:`droptower.rig.lever_decay` exactly like the pymunk scene
(symplectic Euler at the rig's internal step), so plan and simulation agree.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from droptower.damped_cosine import fit_decay, start_frequency_and_decay
from droptower.errors import DroptowerError, expects
from droptower.rheology import Coupling
from droptower.rig.config import RigConfig
from droptower.rig.impact_law import (drop_mass_path, first_period, impact_velocities,
                                      lever_tip_path, second_impact_time)
from droptower.rig.lever_decay import SYMPLECTIC_EULER, LeverDecay, torque_from_rest
from droptower.rig.preload import Pretwist, pretwist
from droptower.sdof import damping_ratio, reference_amplitude

MIN_SAMPLES_PER_PERIOD = 20   # fewer samples per oscillation and the decay fit has too little to work with
MIN_RECORD_PERIODS = 0.75     # Rapp et al. 2022 / docs/theory.md#extraction: at least three quarters of a period after the impact
#: A campaign's record after the impact: this many of the longest predicted first period ...
RECORD_PERIODS = 2.0
#: ... but at least this long (s), rounded up to RECORD_ROUND_S.
MIN_RECORD_S = 0.05
RECORD_ROUND_S = 0.01
#: Record length when the planner finds no complete period (an overdamped coupling).
FALLBACK_RECORD_S = 0.25
CHUNK_STEPS = 1024
MAX_DECAY_S = 2.0             # give up looking for a first period after this long


@dataclass
class FreeDecay:
    """The lever's free decay after the impact: time_s (N,) from the impact; angle_rad (B, N)
    rotation from rest; torque_nm (B, N) the coupling torque itself (preload included, what the
    flange sensor reads; :attr:`torque_from_rest_nm` is T - T_rest, the convention of
    :mod:`droptower.rig.lever_decay`); period_s (B,) time of the angle's second zero crossing
    (NaN if it never came); rest_torque_nm (B,) the torque at rest (the screw's)."""

    time_s: np.ndarray
    angle_rad: np.ndarray
    torque_nm: np.ndarray
    period_s: np.ndarray
    rest_torque_nm: np.ndarray

    @property
    def torque_from_rest_nm(self) -> np.ndarray:
        """T - T_rest (B, N) (N*m): the torque that moves the lever, zero at the impact."""
        return torque_from_rest(self.torque_nm, self.rest_torque_nm)


def free_decay(coupling: Coupling, inertia_kgm2: np.ndarray, rate0_rad_per_s: np.ndarray, twist: Pretwist,
               dt_s: float, min_duration_s: float = 0.0, periods: float = 1.25) -> FreeDecay:
    """Integrate J phi'' = T_screw - T_coupling(twist + phi) from phi = 0, phi' = rate0 (B,).

    Same scheme as the pymunk scene (:data:`droptower.rig.lever_decay.SYMPLECTIC_EULER`); runs until
    every condition has completed ``periods`` of its first period (at least one and a quarter)
    and ``min_duration_s`` has passed (at most :data:`MAX_DECAY_S`).
    """
    screw = twist.torque_nm
    lever = LeverDecay(coupling, twist.state.copy(), inertia_kgm2, rate0_rad_per_s, dt_s, SYMPLECTIC_EULER, screw)
    a_parts, t_parts = [np.zeros((screw.size, 1))], [screw[:, None].copy()]
    n_max = int(math.ceil(MAX_DECAY_S / dt_s))
    period = np.full(screw.size, np.nan)
    while True:
        a_chunk, t_chunk = lever.advance(CHUNK_STEPS)
        a_parts.append(a_chunk)
        t_parts.append(t_chunk)
        angle = np.concatenate(a_parts, axis=1)
        time = np.arange(angle.shape[1]) * dt_s
        # a first period found stays what it is as the record grows: look only where none is yet
        todo = np.isnan(period)
        period[todo] = first_period(time, angle[todo])
        done = np.all(np.isfinite(period)) and time[-1] >= max(min_duration_s, periods * float(np.max(period)))
        if done or angle.shape[1] > n_max:
            break
    return FreeDecay(time_s=time, angle_rad=angle, torque_nm=np.concatenate(t_parts, axis=1), period_s=period,
                     rest_torque_nm=screw.copy())


def record_length_s(period_s: np.ndarray, window_length_s=lambda period: period) -> float:
    """The record after the impact a campaign takes for conditions of these first periods (s):
    :data:`RECORD_PERIODS` times the longest (or the fit window plus half a period, if longer;
    ``window_length_s(period)`` gives the window), at least :data:`MIN_RECORD_S`, rounded up."""
    period = np.asarray(period_s, float)
    if not np.isfinite(period).any():
        return FALLBACK_RECORD_S
    longest = float(np.nanmax(period))
    wanted = max(MIN_RECORD_S, RECORD_PERIODS * longest, window_length_s(longest) + 0.5 * longest)
    return round(math.ceil(wanted / RECORD_ROUND_S - 1e-9) * RECORD_ROUND_S, 6)


#: Periods of the free decay the extractor's starting values read at most (its five zero crossings).
VIEW_PERIODS = 2.75


def extractor_view(time_s: np.ndarray, angle_rad: np.ndarray, period_s: float,
                   record_s: float) -> tuple[float, float, float]:
    """(reference amplitude rad, decay coefficient 1/s, angular frequency rad/s) that ``droptower extract`` reports
    for this free decay (time from the impact): the same starting values, first-cycle window
    and least-squares fit of phi_hat e^(-delta t) cos(omega t - Phi) (Rapp et al. 2022, eq. 13-18).
    On a nonlinear coupling the fitted envelope differs from the peaks by a few per cent, so the
    plan predicts the extractor's numbers, not the peaks'. The decay is read as far as the
    extractor reads a record of ``record_s`` after the impact (its starting frequency averages
    up to five zero crossings) and never beyond :data:`VIEW_PERIODS` of ``period_s``, so a
    condition's view does not depend on the batch it was planned in. NaNs where no cycle
    completes."""

    if not np.isfinite(period_s):
        return np.nan, np.nan, np.nan
    after = (time_s > 0.0) & (time_s <= min(record_s, VIEW_PERIODS * period_s))
    t, y = time_s[after], angle_rad[after]
    try:
        omega0, delta0 = start_frequency_and_decay(t, y, 0.0)
    except DroptowerError:
        return np.nan, np.nan, np.nan
    end = 2.0 * np.pi / omega0
    if t[-1] < end:
        return np.nan, np.nan, np.nan
    sel = t <= end
    amp, delta, omega, _ = fit_decay(t[sel], y[sel], omega0, delta0).params
    return float(reference_amplitude(amp, delta, end)), float(delta), float(omega)


@expects(rig="droptower.rig.config.RigConfig", coupling="droptower.rheology.coupling.Coupling", conditions="pandas.DataFrame")
def plan(rig: RigConfig, coupling: Coupling, conditions: pd.DataFrame, duration_s: float = 0.25) -> pd.DataFrame:
    """Predict each test condition of a plan: amplitude, frequency, damping, double impacts.

    Parameters
    ----------
    rig : RigConfig
        The drop tower (:func:`load_rig`).
    coupling : Coupling
        The coupling under test.
    conditions : DataFrame
        One row per condition (the columns of :meth:`DOE.conditions`).
    duration_s : float, default 0.25
        The record length after the impact (s), for the check that it holds 3/4 of a period.

    Returns
    -------
    DataFrame
        One row per condition: predictions and warnings. Columns shared with ``simulate`` and
        ``extract`` name the same quantity there: ``amplitude_deg`` is the first cycle's φ̂_ref
        (Rapp et al. 2022, eq. 18, the extractor's default window), ``first_peak_deg`` the first
        peak, ``first_period_s`` and ``first_period_frequency_hz`` the first period,
        ``decay_coefficient_per_s``, ``damping_ratio`` from the first cycle's two peaks,
        ``second_impact_after_s``.
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
    decay = free_decay(coupling, J, iv.rate_after_rad_per_s, twist, rig.dt_s, periods=VIEW_PERIODS)
    period = decay.period_s
    horizon = np.where(np.isfinite(period), period, decay.time_s[-1])
    # what follows reads each decay up to its horizon (and the sample after it, where a second
    # impact's crossing is interpolated): the decay runs on to VIEW_PERIODS of the longest period
    # for the extractor's view, so the rest is cut off here rather than masked everywhere
    n = min(int(np.searchsorted(decay.time_s, np.max(horizon), side="right")) + 1, decay.time_s.size)
    t, a, torque = decay.time_s[:n], decay.angle_rad[:, :n], decay.torque_nm[:, :n]
    in_period = t[None, :] <= horizon[:, None]

    # peaks of the first cycle
    first = np.argmax(np.where(in_period, a, -np.inf), axis=1)
    second = np.argmin(np.where(in_period, a, np.inf), axis=1)
    rows = np.arange(len(cond))
    p1, p2 = a[rows, first], a[rows, second]
    t1 = t[first]
    # what the extractor will report: its fit over the first cycle (eq. 13-18)
    seen = np.array([extractor_view(decay.time_s, decay.angle_rad[i], period[i], duration_s)
                     for i in range(len(cond))]).reshape(len(cond), 3)
    delta, omega = seen[:, 1], seen[:, 2]
    peak_torque = np.max(np.where(in_period, np.abs(torque), 0.0), axis=1)

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
    out["impact_impulse_n_s"] = iv.impulse_ns
    out["impact_force_peak_n"] = force_peak
    out["pretwist_deg"] = np.degrees(twist.angle_rad)
    # names shared with simulate and extract mean the same quantity there: amplitude_deg,
    # frequency_hz, decay_coefficient_per_s and damping_ratio are extract's first-cycle fit, the
    # first period and its frequency are simulate's
    out["first_peak_deg"] = np.degrees(p1)
    out["amplitude_deg"] = np.degrees(seen[:, 0])
    out["max_twist_deg"] = np.degrees(np.abs(twist.angle_rad) + np.maximum(p1, np.abs(p2)))
    out["frequency_hz"] = omega / (2.0 * np.pi)
    out["first_period_frequency_hz"] = 1.0 / period
    out["first_period_s"] = period
    out["decay_coefficient_per_s"] = delta
    out["damping_ratio"] = damping_ratio(delta, omega)
    out["peak_torque_nm"] = peak_torque
    out["double_impact"] = np.isfinite(t_second)
    out["second_impact_after_s"] = t_second
    out["min_clearance_mm"] = 1e3 * clearance
    out["samples_per_period"] = period * fs
    out["warnings"] = [_warnings(rig, row, duration_s) for row in out.itertuples(index=False)]
    return out


def _warnings(rig: RigConfig, r, duration_s: float) -> list[str]:
    w = []
    if not any(math.isclose(r.inertia_kgm2, j, rel_tol=1e-9) for j in rig.inertias_kgm2):
        w.append(f"inertia {r.inertia_kgm2:g} kg*m^2 is not a lever fixture of the rig")
    if not any(math.isclose(r.drop_mass_kg, m, rel_tol=1e-9) for m in rig.drop_masses_kg):
        w.append(f"drop mass {r.drop_mass_kg:g} kg is not one of the rig's")
    if math.isnan(r.first_period_s):
        w.append("no complete oscillation (overdamped?)")
    if r.max_twist_deg > rig.coupling_limit_deg:
        w.append(f"twist {r.max_twist_deg:.1f} deg > coupling limit {rig.coupling_limit_deg:g} deg")
    if r.peak_torque_nm > rig.sensors.torque.range_nm:
        w.append(f"torque {r.peak_torque_nm:.0f} N*m > sensor range {rig.sensors.torque.range_nm:g} N*m")
    if r.impact_force_peak_n > rig.sensors.impact_force.range_n:
        w.append(f"impact force {r.impact_force_peak_n:.0f} N > sensor range {rig.sensors.impact_force.range_n:g} N")
    if r.samples_per_period < MIN_SAMPLES_PER_PERIOD:
        w.append(f"only {r.samples_per_period:.0f} samples per period (< {MIN_SAMPLES_PER_PERIOD})")
    if duration_s < MIN_RECORD_PERIODS * r.first_period_s:
        w.append(f"record {duration_s:g} s shorter than 3/4 period ({r.first_period_s:.3g} s)")
    if r.double_impact:
        w.append(f"double impact at {1e3 * r.second_impact_after_s:.1f} ms (period {1e3 * r.first_period_s:.1f} ms)")
    return w
