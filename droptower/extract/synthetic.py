"""Synthetic drop-test logs with known stiffness and damping: the linear single-degree-of-
freedom free decay after a short impact (docs/theory.md#decay), as a drop-tower amplifier records it.

Angle: φ(t) = φ̂·e^(−δτ)·sin(ωτ), τ = time since the impact (lever at rest before it); with
a second impact the closed-form response to the second kick is superposed (the system is
linear). Torque of the linear Kelvin–Voigt coupling: T = c·φ + d·φ' with d = 2Jδ (so that
c = J(ω² + δ²), eq. 15), plus an optional decaying test-setup ringing (500–800 Hz) that the
angle does not see (Rapp et al. 2022, Fig. 9). Impact force: a half-sine pulse whose impulse ∫F dt
= J·φ'(0)/L gives the lever its start velocity (docs/theory.md#impact), sampled as the average over
each sample interval (the amplifier's anti-aliasing filter), so a pulse shorter than a sample
still shows up at 2048 Hz. Sensor offsets, a preload and white noise on every channel.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from droptower.sdof import decay_ratio
from droptower.io.droptower_log import write_log
from droptower.io.signals import DropSignals
from droptower.rates import RIG_SAMPLE_RATE_HZ


@dataclass(frozen=True)
class SyntheticDrop:
    """One synthetic drop test; all fields SI except the ``_deg`` ones.

    damping_ratio is the drop tower's d_ratio (eq. 16): δ/ω = ln(1 + 2 d_ratio)/(4π).
    amplitude_deg: φ̂ of the undamped sine envelope at the impact. ringing_fraction: ringing
    amplitude relative to c·φ̂. second_impact_after_s: time of a second impact after the first
    (None: none), with second_impact_fraction of the first impulse, pushing the same way.
    """

    inertia_kgm2: float = 0.359
    stiffness_nm_per_rad: float = 14_000.0
    damping_ratio: float = 1.5
    amplitude_deg: float = 1.0
    sample_rate_hz: float = RIG_SAMPLE_RATE_HZ
    duration_s: float = 0.25
    pretrigger_s: float = 0.02
    preload_nm: float = 0.0
    angle_offset_deg: float = 0.3
    torque_offset_nm: float = 15.0
    angle_noise_deg: float = 0.002
    torque_noise_nm: float = 2.0
    force_noise_n: float = 20.0
    pulse_s: float = 3e-4
    lever_length_m: float = 0.2
    ringing_hz: float = 650.0
    ringing_fraction: float = 0.0
    ringing_decay_per_s: float = 40.0
    second_impact_after_s: float | None = None
    second_impact_fraction: float = 0.3
    seed: int = 0

    @property
    def omega(self) -> float:
        """Damped angular frequency ω (rad/s): c = J ω²(1 + r²)."""
        r = float(decay_ratio(self.damping_ratio))
        return math.sqrt(self.stiffness_nm_per_rad / (self.inertia_kgm2 * (1.0 + r * r)))

    @property
    def delta(self) -> float:
        """Decay coefficient δ (1/s)."""
        return float(decay_ratio(self.damping_ratio)) * self.omega

    @property
    def impact_velocity_rad_per_s(self) -> float:
        """φ'(0+) = φ̂·ω."""
        return math.radians(self.amplitude_deg) * self.omega

    def _kick(self, time: np.ndarray, at: float, velocity: float) -> tuple[np.ndarray, np.ndarray]:
        """Angle and angular velocity of the free decay started at ``at`` with φ'(at) = velocity."""
        tau = time - at
        on = tau >= 0.0
        tau = np.where(on, tau, 0.0)
        env = (velocity / self.omega) * np.exp(-self.delta * tau) * on
        phi = env * np.sin(self.omega * tau)
        dphi = env * (self.omega * np.cos(self.omega * tau) - self.delta * np.sin(self.omega * tau))
        return phi, dphi

    def _pulse(self, time: np.ndarray, start: float, impulse: float) -> np.ndarray:
        """Half-sine force pulse of ``impulse`` N·s, averaged over each sample interval."""
        half = 0.5 / self.sample_rate_hz

        def area(t: np.ndarray) -> np.ndarray:  # ∫ F dt from -inf to t
            return 0.5 * impulse * (1.0 - np.cos(np.pi * np.clip(t - start, 0.0, self.pulse_s) / self.pulse_s))

        return (area(time + half) - area(time - half)) * self.sample_rate_hz

    def channels(self) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """(time_s, {"angle_rad", "torque_nm", "impact_force_n"}) as the amplifier records them."""
        rng = np.random.default_rng(self.seed)
        n = int(round(self.duration_s * self.sample_rate_hz))
        time = np.arange(n) / self.sample_rate_hz
        hit = self.pretrigger_s + 0.5 * self.pulse_s  # the lever moves from the pulse's centre
        v0 = self.impact_velocity_rad_per_s
        phi, dphi = self._kick(time, hit, v0)
        impulse = self.inertia_kgm2 * v0 / self.lever_length_m
        force = self._pulse(time, self.pretrigger_s, impulse)
        if self.second_impact_after_s is not None:
            phi2, dphi2 = self._kick(time, hit + self.second_impact_after_s, self.second_impact_fraction * v0)
            phi, dphi = phi + phi2, dphi + dphi2
            force += self._pulse(time, self.pretrigger_s + self.second_impact_after_s,
                                 self.second_impact_fraction * impulse)
        damping = 2.0 * self.inertia_kgm2 * self.delta
        torque = self.stiffness_nm_per_rad * phi + damping * dphi
        if self.ringing_fraction:
            tau = np.clip(time - hit, 0.0, None)
            ringing = self.ringing_fraction * self.stiffness_nm_per_rad * math.radians(self.amplitude_deg)
            torque += (time >= hit) * ringing * np.exp(-self.ringing_decay_per_s * tau) * np.sin(
                2 * np.pi * self.ringing_hz * tau)
        # preload: the coupling sits twisted by T0/c before the drop; sensors have offsets
        angle = (phi + self.preload_nm / self.stiffness_nm_per_rad + math.radians(self.angle_offset_deg)
                 + rng.normal(0.0, math.radians(self.angle_noise_deg), n))
        torque = torque + self.preload_nm + self.torque_offset_nm + rng.normal(0.0, self.torque_noise_nm, n)
        force = force + rng.normal(0.0, self.force_noise_n, n)
        return time, {"angle_rad": angle, "torque_nm": torque, "impact_force_n": force}

    def metadata(self) -> dict:
        """Test metadata as the virtual rig writes it, plus the true values (``true_*``)."""
        return {"inertia_kgm2": self.inertia_kgm2, "preload_nm": self.preload_nm, "seed": self.seed,
                "lever_length_m": self.lever_length_m,
                "true_stiffness_nm_per_rad": self.stiffness_nm_per_rad, "true_damping_ratio": self.damping_ratio,
                "true_frequency_hz": self.omega / (2 * np.pi), "synthetic": asdict(self)}

    def signals(self) -> DropSignals:
        """The test as SI :class:`DropSignals` (what the extractor consumes)."""
        time, ch = self.channels()
        return DropSignals(time_s=time, angle_rad=ch["angle_rad"], torque_nm=ch["torque_nm"],
                           impact_force_n=ch["impact_force_n"], metadata=self.metadata())

    def write(self, path: str | Path) -> Path:
        """Write the test as a droptower log (``.csv`` or ``.parquet``)."""
        time, ch = self.channels()
        return write_log(path, time, ch, self.metadata())
