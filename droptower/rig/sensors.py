"""Sampling a simulated drop test like the real rig's sensors (seed 004 "Experimental Setup").

- Laser distance sensor on the lever: ``laser_distance_m = radius * angle + noise``, the arc
  length at the spot radius (the conversion the log post-processor inverts: angle =
  distance / radius, :func:`droptower.io.mapping.map_channels`). The angle is the coupling's
  total twist, preload twist included; ``angle_rad`` is the laser distance divided by the
  radius, so it carries the laser's noise.
- Flange torque (force sensor on the coupling flange): the coupling torque, preload included,
  seen through the optional test-setup resonance (seed 004 Fig. 8: ringing on the torque that
  the angle does not show): T_meas = T + s (H(T) - T), H the 2nd-order low-pass
  w^2 / (p^2 + 2 z w p + w^2), discretised with a zero-order hold at the sample rate, starting
  at rest at the pre-trigger torque. Then noise, and saturation at the sensor's range.
- Impact force (piezo sensor at the lever tip): every contact as a half-sine pulse of the
  configured contact duration (seed 004: ~0.3 ms), centred on the simulated contact time (the
  rigid impact is the limit of a symmetric pulse, so the lever's velocity jump sits at the
  pulse's centroid) and scaled so that its samples sum to exactly the simulated impulse
  (sum F dt = impulse). Then noise and saturation.

Noise is white and Gaussian, drawn from independent streams of one seed: same seed, same log.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import signal

from droptower.rig.config import Resonance, Sensors


@dataclass(frozen=True)
class Channels:
    """Sampled channels of one test (each (N,)), plus notes on saturation."""

    time_s: np.ndarray
    angle_rad: np.ndarray
    torque_nm: np.ndarray
    impact_force_n: np.ndarray
    laser_distance_m: np.ndarray
    saturated: tuple[str, ...] = ()

    def columns(self) -> dict[str, np.ndarray]:
        """The log columns after ``time_s``, named with their units."""
        return {"angle_rad": self.angle_rad, "torque_nm": self.torque_nm, "impact_force_n": self.impact_force_n,
                "laser_distance_m": self.laser_distance_m}


def resonance(torque_nm: np.ndarray, sample_rate_hz: float, res: Resonance) -> np.ndarray:
    """The torque seen through the test-setup resonance: T + s (H(T) - T)."""
    w = 2.0 * np.pi * res.frequency_hz
    b, a, _ = signal.cont2discrete(([w * w], [1.0, 2.0 * res.damping_ratio * w, w * w]), 1.0 / sample_rate_hz,
                                   method="zoh")
    b = np.ravel(b)
    zi = signal.lfilter_zi(b, a) * torque_nm[0]
    filtered, _ = signal.lfilter(b, a, torque_nm, zi=zi)
    return torque_nm + res.strength * (filtered - torque_nm)


def force_pulses(time_s: np.ndarray, contact_times_s: np.ndarray, impulses_ns: np.ndarray,
                 duration_s: float) -> np.ndarray:
    """Half-sine pulses of ``duration_s`` centred on each contact, each with sum F dt = impulse."""
    force = np.zeros_like(time_s)
    dt = (time_s[-1] - time_s[0]) / (time_s.size - 1)
    for t_c, impulse in zip(np.atleast_1d(contact_times_s), np.atleast_1d(impulses_ns)):
        phase = (time_s - t_c) / duration_s + 0.5
        inside = (phase > 0.0) & (phase < 1.0)
        shape = np.where(inside, np.sin(np.pi * np.clip(phase, 0.0, 1.0)), 0.0)
        total = shape.sum() * dt
        if total == 0.0:  # a pulse shorter than a sample: all of it in the nearest sample
            j = int(np.clip(np.rint((t_c - time_s[0]) / dt), 0, time_s.size - 1))
            force[j] += impulse / dt
        else:
            force += impulse * shape / total
    return force


def sample(time_s: np.ndarray, twist_rad: np.ndarray, coupling_torque_nm: np.ndarray,
           contact_times_s: np.ndarray, impulses_ns: np.ndarray, sensors: Sensors, seed: int) -> Channels:
    """The channels the rig would record for one test.

    time_s (N,) at the sample rate; twist_rad (N,) the coupling's total twist; coupling_torque_nm
    (N,) its torque; contacts (times, impulses in N*s); ``seed`` fixes the noise.
    """
    n = time_s.size
    laser_rng, torque_rng, force_rng = (np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(3))
    radius = sensors.laser.radius_m
    distance = radius * twist_rad + laser_rng.normal(0.0, sensors.laser.noise_m, n)
    torque = coupling_torque_nm
    if sensors.torque.resonance is not None:
        torque = resonance(torque, sensors.sample_rate_hz, sensors.torque.resonance)
    torque = torque + torque_rng.normal(0.0, sensors.torque.noise_nm, n)
    force = force_pulses(time_s, contact_times_s, impulses_ns, sensors.impact_force.contact_duration_s)
    force = force + force_rng.normal(0.0, sensors.impact_force.noise_n, n)
    saturated = []
    if np.any(np.abs(torque) > sensors.torque.range_nm):
        saturated.append("torque_nm")
        torque = np.clip(torque, -sensors.torque.range_nm, sensors.torque.range_nm)
    if np.any(np.abs(force) > sensors.impact_force.range_n):
        saturated.append("impact_force_n")
        force = np.clip(force, -sensors.impact_force.range_n, sensors.impact_force.range_n)
    return Channels(time_s=time_s, angle_rad=distance / radius, torque_nm=torque, impact_force_n=force,
                    laser_distance_m=distance, saturated=tuple(saturated))
