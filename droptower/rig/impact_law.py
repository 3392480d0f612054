"""Closed forms of the drop-tower impact and free decay (docs/theory.md#impact, #decay, Rapp et al. 2022, eq. 1-12).

Sign convention throughout: positive = downwards for velocities and paths, positive angle =
the direction the impact turns the lever. All functions take numpy arrays (any shape that
broadcasts) or floats.

The impact law is the corrected one of docs/theory.md#impact (momentum and Newton's restitution law);
the printed eq. 6, 7 and 9 of Rapp et al. 2022 do not conserve momentum and are not used.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from droptower.units import GRAVITY_M_PER_S2

G = GRAVITY_M_PER_S2  # m/s^2: defined once, in droptower.units (a rig file may give its own)


@dataclass(frozen=True)
class ImpactVelocities:
    """Velocities and energies of one impact (each an array of the broadcast shape).

    impact_m_per_s: v1 = sqrt(2 g h); drop_mass_after_m_per_s: v1'; lever_tip_after_m_per_s:
    v2'; rate_after_rad_per_s: phi'(0+) = v2'/L; equivalent_mass_kg: m2 = J/L^2;
    impact_energy_j: E_imp = 1/2 J phi'(0+)^2, the energy the lever takes up;
    restitution_loss_j: kinetic energy lost in the contact; impulse_ns: m1 (v1 - v1') in N*s.
    """

    impact_m_per_s: np.ndarray
    drop_mass_after_m_per_s: np.ndarray
    lever_tip_after_m_per_s: np.ndarray
    rate_after_rad_per_s: np.ndarray
    equivalent_mass_kg: np.ndarray
    impact_energy_j: np.ndarray
    restitution_loss_j: np.ndarray
    impulse_ns: np.ndarray


def impact_velocities(drop_mass_kg, inertia_kgm2, lever_length_m, height_m, restitution,
                      gravity_m_per_s2: float = G) -> ImpactVelocities:
    """docs/theory.md#impact: the lever as the equivalent mass m2 = J/L^2 at rest, hit by m1 at sqrt(2 g h).

        v1' = v1 (m1 - k m2) / (m1 + m2),   v2' = v1 m1 (1 + k) / (m1 + m2),   phi'(0+) = v2'/L
    """
    m1 = np.asarray(drop_mass_kg, float)
    m2 = np.asarray(inertia_kgm2, float) / np.asarray(lever_length_m, float) ** 2
    k = np.asarray(restitution, float)
    v1 = np.sqrt(2.0 * gravity_m_per_s2 * np.asarray(height_m, float))
    v1_after = v1 * (m1 - k * m2) / (m1 + m2)
    v2_after = v1 * m1 * (1.0 + k) / (m1 + m2)
    rate = v2_after / np.asarray(lever_length_m, float)
    reduced = m1 * m2 / (m1 + m2)
    return ImpactVelocities(
        impact_m_per_s=v1, drop_mass_after_m_per_s=v1_after, lever_tip_after_m_per_s=v2_after,
        rate_after_rad_per_s=rate, equivalent_mass_kg=m2,
        impact_energy_j=0.5 * np.asarray(inertia_kgm2, float) * rate ** 2,
        restitution_loss_j=0.5 * reduced * v1 ** 2 * (1.0 - k ** 2),
        impulse_ns=m1 * (v1 - v1_after))


def linear_free_decay(stiffness_nm_per_rad, damping_nms_per_rad, inertia_kgm2, rate0_rad_per_s, t_s):
    """docs/theory.md#decay: J phi'' + d phi' + c phi = 0 from phi(0) = 0, phi'(0) = rate0 (underdamped).

    phi(t) = rate0/omega e^(-delta t) sin(omega t), delta = d/(2J), omega = sqrt(c/J - delta^2).
    Returns (angle_rad, delta_per_s, omega_rad_per_s).
    """
    delta = np.asarray(damping_nms_per_rad, float) / (2.0 * np.asarray(inertia_kgm2, float))
    omega2 = np.asarray(stiffness_nm_per_rad, float) / np.asarray(inertia_kgm2, float) - delta ** 2
    if np.any(omega2 <= 0):
        raise ValueError("the linear oscillator is not underdamped (D >= 1)")
    omega = np.sqrt(omega2)
    t = np.asarray(t_s, float)
    return np.asarray(rate0_rad_per_s, float) / omega * np.exp(-delta * t) * np.sin(omega * t), delta, omega


def drop_mass_path(velocity_after_m_per_s, t_s, gravity_m_per_s2: float = G):
    """Rapp et al. 2022, eq. 10: x1(t) = v1' t + g t^2 / 2 below the impact point (m, positive down)."""
    t = np.asarray(t_s, float)
    return np.asarray(velocity_after_m_per_s, float) * t + 0.5 * gravity_m_per_s2 * t ** 2


def lever_tip_path(angle_rad, lever_length_m):
    """Where the lever meets the vertical line of the striker: x2 = L tan(phi) (m, positive down).

    The drop mass is guided vertically at horizontal distance L from the axis, so it meets the
    lever's top line at L tan(phi) (docs/theory.md#decay writes L phi or L sin phi; the difference is
    below 0.1 % of x2 for the few degrees of a drop test).
    """
    return np.asarray(lever_length_m, float) * np.tan(np.asarray(angle_rad, float))


def second_impact_time(t_s: np.ndarray, x_mass_m: np.ndarray, x_tip_m: np.ndarray,
                       horizon_s: np.ndarray | float = np.inf) -> np.ndarray:
    """docs/theory.md#decay: the first time the drop mass reaches the lever tip again (x1 >= x2).

    t_s (N,) from the impact (t_s[0] = 0); x_mass_m, x_tip_m (..., N) paths from
    :func:`drop_mass_path` and :func:`lever_tip_path`. The search starts once the two have
    separated (x2 > x1) and ends at ``horizon_s`` (the paper: one oscillation period); the
    crossing is located by linear interpolation between samples. Returns the time in s, NaN
    where there is none.
    """
    gap = np.asarray(x_tip_m, float) - np.asarray(x_mass_m, float)
    gap2 = gap.reshape(-1, gap.shape[-1])
    horizon = np.broadcast_to(np.asarray(horizon_s, float), gap.shape[:-1]).reshape(-1)
    out = np.full(gap2.shape[0], np.nan)
    for i, g in enumerate(gap2):
        apart = np.flatnonzero(g > 0)
        if apart.size == 0:
            continue
        after = np.flatnonzero(g[apart[0]:] <= 0)
        if after.size == 0:
            continue
        j = apart[0] + after[0]
        # gap goes from > 0 at j-1 to <= 0 at j: interpolate the zero
        t_cross = t_s[j - 1] + (t_s[j] - t_s[j - 1]) * g[j - 1] / (g[j - 1] - g[j])
        if t_cross <= horizon[i]:
            out[i] = t_cross
    return out.reshape(gap.shape[:-1]) if gap.ndim > 1 else out[0]


def first_period(t_s: np.ndarray, angle_rad: np.ndarray) -> np.ndarray:
    """The first oscillation period after an impact at ``t_s[0]``: the time of the angle's
    rising zero crossing that follows its first falling one (linear interpolation).

    angle_rad (..., N) starts at rest (0) and swings positive first. NaN where the record
    holds no complete period (overdamped, or too short).
    """
    a = np.asarray(angle_rad, float)
    rows = a.reshape(-1, a.shape[-1])
    out = np.full(rows.shape[0], np.nan)
    for i, row in enumerate(rows):
        down = np.flatnonzero((row[:-1] > 0) & (row[1:] <= 0))
        if down.size == 0:
            continue
        up = np.flatnonzero((row[down[0]:-1] < 0) & (row[down[0] + 1:] >= 0))
        if up.size:
            j = down[0] + up[0]
            out[i] = t_s[j] + (t_s[j + 1] - t_s[j]) * row[j] / (row[j] - row[j + 1]) - t_s[0]
    return out.reshape(a.shape[:-1]) if a.ndim > 1 else out[0]
