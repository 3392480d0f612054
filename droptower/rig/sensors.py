"""Sampling a simulated drop test like the real rig's sensors (Rapp et al. 2022 "Experimental Setup").

- Laser distance sensor looking at the lever along a fixed vertical line at the spot radius:
  ``laser_distance_m = radius * tan(angle) + noise`` (:func:`droptower.io.mapping.laser_distance`,
  the geometry of the impact point's L tan(phi); the log reader inverts it with
  :func:`~droptower.io.mapping.laser_angle`). The angle is the coupling's total twist, preload
  twist included; ``angle_rad`` is the angle read back from the laser distance, so it carries
  the laser's noise.
- Flange torque (force sensor on the coupling flange): the coupling torque, preload included,
  seen through the optional test-setup resonance (Rapp et al. 2022, Fig. 8: ringing on the torque that
  the angle does not show): T_meas = T + s (H(T) - T), H the 2nd-order low-pass
  w^2 / (p^2 + 2 z w p + w^2), discretised with a zero-order hold at the sample rate, starting
  at rest at the pre-trigger torque. Then noise, and saturation at the sensor's range.
- Impact force (piezo sensor at the lever tip): the simulated contact force history (the
  impulses of every solver step, :mod:`.scene`), each impulse seen as a half-sine pulse of the
  configured contact duration (Rapp et al. 2022: ~0.3 ms) centred on its time (the rigid impact is the
  limit of a symmetric pulse, so the lever's velocity jump sits at the pulse's centroid) and
  scaled so that its samples sum to exactly the impulse (sum F dt = impulse). The impact, a
  single-step impulse, becomes one 0.3 ms pulse; the drop mass resting on the lever, a long
  train of small impulses, a low force as long as the contact (its weight, give or take the
  lever's motion). Then noise and saturation.

Noise is white and Gaussian, drawn from independent streams of one seed: same seed, same log.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
from scipy import signal

from droptower.io.mapping import laser_angle, laser_distance
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


@functools.lru_cache(maxsize=64)
def _zoh_filter(frequency_hz: float, damping_ratio: float, sample_rate_hz: float) -> tuple[np.ndarray, ...]:
    """(b, a, zi at unit input) of the resonance's low-pass H, zero-order hold at the sample rate.
    The same for every test of a rig: computed once (a matrix exponential, ~5 ms)."""
    w = 2.0 * np.pi * frequency_hz
    b, a, _ = signal.cont2discrete(([w * w], [1.0, 2.0 * damping_ratio * w, w * w]), 1.0 / sample_rate_hz,
                                   method="zoh")
    b = np.ravel(b)
    out = (b, np.asarray(a), signal.lfilter_zi(b, a))
    for array in out:
        array.setflags(write=False)  # shared by every later call
    return out


def resonance(torque_nm: np.ndarray, sample_rate_hz: float, res: Resonance) -> np.ndarray:
    """The torque seen through the test-setup resonance: T + s (H(T) - T)."""
    b, a, zi_unit = _zoh_filter(float(res.frequency_hz), float(res.damping_ratio), float(sample_rate_hz))
    zi = zi_unit * torque_nm[0]
    filtered, _ = signal.lfilter(b, a, torque_nm, zi=zi)
    return torque_nm + res.strength * (filtered - torque_nm)


def force_pulses(time_s: np.ndarray, times_s: np.ndarray, impulses_ns: np.ndarray, duration_s: float) -> np.ndarray:
    """The force of impulses (N*s) delivered at ``times_s`` (s), sampled at ``time_s`` (N,).

    Each impulse is a half-sine pulse of ``duration_s`` centred on its time with sum F dt =
    impulse, also where the pulse is cut by the record's ends; impulses outside the record go to
    its first or last sample. Pass one impulse per contact for ideal impacts, or a contact's
    impulse history (e.g. per sample) for a force that lasts as long as the contact.
    """
    n = time_s.size
    dt = (time_s[-1] - time_s[0]) / (n - 1)
    # each impulse shared linearly between the two samples around it: sum and centroid stay exact
    position = np.clip((np.atleast_1d(times_s) - time_s[0]) / dt, 0.0, n - 1)
    lo = np.minimum(position.astype(int), n - 2)
    share = position - lo
    impulse = np.zeros(n)
    np.add.at(impulse, lo, (1.0 - share) * impulses_ns)
    np.add.at(impulse, lo + 1, share * impulses_ns)
    # the half-sine on the sample grid, unit sum (a pulse shorter than a sample is one sample)
    half = 0.5 * duration_s / dt
    j = np.arange(-int(np.ceil(half)), int(np.ceil(half)) + 1)
    kernel = np.where(np.abs(j) < half, np.cos(0.5 * np.pi * j / half), 0.0)
    kernel /= kernel.sum()
    m = j.size // 2

    def spread(x: np.ndarray) -> np.ndarray:
        return np.convolve(x, kernel)[m:m + n]

    # a pulse cut by the record's ends keeps its impulse: scale by the share of it inside
    return spread(impulse / spread(np.ones(n))) / dt


def sample(time_s: np.ndarray, twist_rad: np.ndarray, coupling_torque_nm: np.ndarray,
           contact_times_s: np.ndarray, impulses_ns: np.ndarray, sensors: Sensors, seed: int) -> Channels:
    """The channels the rig would record for one test.

    time_s (N,) at the sample rate; twist_rad (N,) the coupling's total twist; coupling_torque_nm
    (N,) its torque; contact impulses (their times in s and impulses in N*s, as taken by
    :func:`force_pulses`); ``seed`` fixes the noise.
    """
    n = time_s.size
    laser_rng, torque_rng, force_rng = (np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(3))
    radius = sensors.laser.radius_m
    distance = laser_distance(twist_rad, radius) + laser_rng.normal(0.0, sensors.laser.noise_m, n)
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
    return Channels(time_s=time_s, angle_rad=laser_angle(distance, radius), torque_nm=torque, impact_force_n=force,
                    laser_distance_m=distance, saturated=tuple(saturated))
