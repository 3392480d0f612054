"""The exact steady state of a coupling under sine excitation, for model analysis.

The bench (:mod:`droptower.servo.bench`) evaluates like a test lab (acquisition rate,
smoothing, preload found by iteration, one frequency at a time). Calibrating or checking a
model needs something else: many (amplitude, frequency) pairs at once, evaluated exactly. Here
every pair is a row of one batched core call (rows of similar duration share a batch), driven
at the simulation step itself, and the torque of the last ``cycles`` cycles is projected onto
the harmonics of the excitation (a discrete Fourier projection over whole cycles: exact for
a periodic steady state, with no smoothing).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from droptower.errors import DroptowerError
from droptower.rates import RIG_SAMPLE_RATE_HZ
from droptower.rheology import Coupling

#: fewest simulation steps per cycle (the kernels see the angle linear between steps)
MIN_STEPS_PER_CYCLE = 4096


@dataclass(frozen=True)
class SteadyState:
    """Per row (B,): storage and loss stiffness (N*m/rad, first harmonic, the elastoslide paper, eq. 6), the
    loss factor; ``harmonic_ratio`` (B, harmonics + 1): |T_n| / |T_1| for n = 0 .. harmonics
    (n = 0: the mean torque over the first harmonic's amplitude)."""

    storage_stiffness_nm_per_rad: np.ndarray
    loss_stiffness_nm_per_rad: np.ndarray
    harmonic_ratio: np.ndarray

    @property
    def loss_factor(self) -> np.ndarray:
        return self.loss_stiffness_nm_per_rad / self.storage_stiffness_nm_per_rad


def steady_state(coupling: Coupling, amplitudes_rad: ArrayLike, frequencies_hz: ArrayLike, *, cycles: int = 5,
                 run_in_cycles: int = 5, simulation_rate_hz: float = RIG_SAMPLE_RATE_HZ, harmonics: int = 1) -> SteadyState:
    """Drive each row with x = A sin(2 pi f t) (amplitude rising over the first cycle) from a
    virgin state and evaluate the last ``cycles`` of ``run_in_cycles + cycles``."""
    amps = np.atleast_1d(np.asarray(amplitudes_rad, float))
    freqs = np.broadcast_to(np.asarray(frequencies_hz, float), amps.shape).copy()
    if not (np.all(np.isfinite(amps)) and np.all(amps > 0) and np.all(np.isfinite(freqs)) and np.all(freqs > 0)):
        raise DroptowerError("steady state: amplitudes and frequencies must be positive and finite")
    storage, loss = np.empty(amps.size), np.empty(amps.size)
    ratio = np.empty((amps.size, harmonics + 1))
    order = np.argsort(freqs)
    while order.size:
        # rows whose durations lie within a factor 2 of the longest share a batch
        rows = order[freqs[order] <= 2 * freqs[order].min()]
        order = order[~np.isin(order, rows)]
        rate = max(simulation_rate_hz, MIN_STEPS_PER_CYCLE * freqs[rows].max())
        n = int(np.ceil((run_in_cycles + cycles) / freqs[rows].min() * rate))
        t = np.arange(1, n + 1) / rate
        phase = freqs[rows, None] * t[None, :]
        x = amps[rows, None] * np.clip(phase, 0.0, 1.0) * np.sin(2 * np.pi * phase)
        torque = coupling.simulate(x, 1.0 / rate, record_energy=False).torque_nm
        for j, i in enumerate(rows):
            steps_per_cycle = rate / freqs[i]
            lo = int(round(run_in_cycles * steps_per_cycle))
            hi = int(round((run_in_cycles + cycles) * steps_per_cycle))
            w = 2 * np.pi * freqs[i] * t[lo:hi]
            seg = torque[j, lo:hi]
            coef = [2 * np.mean(seg * np.exp(-1j * k * w)) for k in range(harmonics + 1)]
            coef[0] = coef[0] / 2
            first = 1j * coef[1]  # T ~ Re(first e^{iwt}) relative to x = A sin(wt): K' + i K''
            storage[i], loss[i] = first.real / amps[i], first.imag / amps[i]
            ratio[i] = np.abs(coef) / abs(coef[1])
    return SteadyState(storage, loss, ratio)


def rubber_figures(coupling: Coupling, amplitude_rad: float = np.radians(1.5), frequency_hz: float = 30.0,
                   low_frequency_hz: float = 1.0) -> dict[str, float]:
    """How rubber-like a coupling's steady state is (the reference coupling's criteria, at 1.5 deg by default):
    ``loss_factor_ratio`` eta(low_frequency_hz) / eta(frequency_hz) (filled rubber: weakly
    frequency dependent, >= 0.7 from 1 to 30 Hz), ``storage_rise_pct_per_decade``, the mean rise
    of K' per decade from low_frequency_hz to frequency_hz (filled rubber: a few to tens of %),
    and ``third_harmonic_pct``, the torque's third harmonic in percent of its fundamental at
    (amplitude, frequency_hz) (elliptic loops: small)."""
    at = steady_state(coupling, [amplitude_rad], [frequency_hz], harmonics=3)
    low = steady_state(coupling, [amplitude_rad], [low_frequency_hz])
    decades = np.log10(frequency_hz / low_frequency_hz)
    rise = (at.storage_stiffness_nm_per_rad[0] / low.storage_stiffness_nm_per_rad[0]) ** (1 / decades) - 1
    return {"loss_factor_ratio": float(low.loss_factor[0] / at.loss_factor[0]),
            "storage_rise_pct_per_decade": float(100 * rise),
            "third_harmonic_pct": float(100 * at.harmonic_ratio[0, 3]),
            "loss_factor": float(at.loss_factor[0])}
