"""Shared helpers of the rheology and preset tests (no tests in here).

Everything a test compares against is computed here independently of the library: work by
the trapezoidal rule from the torque and angle histories, first harmonics by projection on
whole sampled cycles, histories from their closed forms.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from droptower.rheology import parse_coupling

REPO = Path(__file__).resolve().parents[1]
PRESET_DIR = REPO / "rig_configs" / "couplings"

#: Representative excitation of each shipped preset: (amplitude in the file's length unit,
#: rad or m, and frequency in Hz), from the ranges its source tested. Presets not listed fall
#: back to DEFAULT_SCALE of their units.
PRESET_SCALE = {
    "rapp2022_nr60": (np.deg2rad(1.5), 40.0),     # Rapp et al. 2022: 0.15-3.2 deg, 20-60 Hz
    "seed001_specimen": (2.5e-3, 2.5),           # the elastoslide paper, Fig. 9: 2.5 mm, 2.5 Hz
    "seed001_lag_damper": (2.5e-3, 5.0),         # the elastoslide paper: 0.25-5 mm, lag/rev 5 Hz
    "seed002_bushing": (0.5e-3, 10.0),           # Scheiblegger et al. 2013: +-0.1 and 1 mm at 10 Hz
    "seed003_masing": (0.02, 10.0),              # Heine & Plagemann 2014: 2-20 Hz (normalised amplitudes)
    "seed000_six_parameter": (0.02, 15.0),       # the zero-dimensional model paper: 5-25 Hz sweeps
}
DEFAULT_SCALE = {"torsional": (np.deg2rad(1.5), 20.0), "translational": (1e-3, 10.0)}


def preset_paths() -> list[Path]:
    """Every shipped coupling preset (``rig_configs/couplings/*.toml``)."""
    return sorted(PRESET_DIR.glob("*.toml"))


def preset_scale(coupling) -> tuple[float, float]:
    """(amplitude, frequency_hz) representative of a preset."""
    return PRESET_SCALE.get(coupling.name, DEFAULT_SCALE[coupling.units])


def single(element: dict):
    """A coupling of one element given as the dict of its ``[[element]]`` table."""
    return parse_coupling({"element": [element]})


def trapezoid_work(angle: np.ndarray, torque: np.ndarray) -> np.ndarray:
    """Cumulative work done on the coupling (J), sum of 1/2 (T_n + T_n+1)(x_n+1 - x_n).

    The history starts from the virgin state (angle 0, torque 0): the first step is
    included. Works along the last axis.
    """
    x = np.concatenate([np.zeros(angle.shape[:-1] + (1,)), angle], axis=-1)
    t = np.concatenate([np.zeros(torque.shape[:-1] + (1,)), torque], axis=-1)
    return np.cumsum(0.5 * (t[..., 1:] + t[..., :-1]) * np.diff(x, axis=-1), axis=-1)


def sine(amplitude: float, frequency_hz: float, samples_per_cycle: int, cycles: float,
         offset: float = 0.0) -> tuple[np.ndarray, np.ndarray, float]:
    """(t, angle, dt): offset + amplitude sin(2 pi f t) at t = dt, 2 dt, ... (t = 0 is the
    virgin state, so the sample count is an integer number of samples per cycle)."""
    dt = 1.0 / (frequency_hz * samples_per_cycle)
    t = np.arange(1, int(round(cycles * samples_per_cycle)) + 1) * dt
    return t, offset + amplitude * np.sin(2 * np.pi * frequency_hz * t), dt


def first_harmonic(t: np.ndarray, torque: np.ndarray, amplitude: float, frequency_hz: float,
                   samples_per_cycle: int, cycles: int = 1) -> tuple[float, float]:
    """Storage and loss stiffness (K', K'') of the last ``cycles`` whole cycles.

    For angle = A sin(w t) the first harmonic of the torque is A (K' sin(w t) + K'' cos(w t));
    projection over whole, uniformly sampled cycles is exact for the harmonics below the
    Nyquist frequency.
    """
    n = samples_per_cycle * cycles
    w = 2 * np.pi * frequency_hz * t[-n:]
    tq = torque[..., -n:]
    return (2.0 * np.mean(tq * np.sin(w), axis=-1) / amplitude,
            2.0 * np.mean(tq * np.cos(w), axis=-1) / amplitude)


def random_smooth(rng: np.random.Generator, t: np.ndarray, frequency_hz: float, n_modes: int = 6) -> np.ndarray:
    """A band-limited random history (zero at t = 0), unit scale: a sum of sines with random
    frequencies in [0.2, 3] x frequency_hz and random phases, faded in over the first period."""
    freqs = frequency_hz * rng.uniform(0.2, 3.0, n_modes)
    phases = rng.uniform(0, 2 * np.pi, n_modes)
    amps = rng.uniform(0.3, 1.0, n_modes) / n_modes
    x = (amps[:, None] * (np.sin(2 * np.pi * freqs[:, None] * t + phases[:, None]) - np.sin(phases[:, None]))).sum(0)
    return x * np.clip(t * frequency_hz, 0.0, 1.0)


def band_limited(rng: np.random.Generator, rate_hz: float, duration_s: float, lo_hz: float, hi_hz: float,
                 rms: float) -> np.ndarray:
    """A random history with a flat spectrum in [lo_hz, hi_hz] (random phases), scaled to ``rms``,
    starting from 0 (a smoothstep ramp-in over its first 50 ms)."""
    n = int(rate_hz * duration_s)
    f = np.fft.rfftfreq(n, 1 / rate_hz)
    spectrum = np.where((f >= lo_hz) & (f <= hi_hz), np.exp(2j * np.pi * rng.random(f.size)), 0.0)
    x = np.fft.irfft(spectrum, n)
    x *= rms / np.sqrt(np.mean(x ** 2))
    ramp = np.clip(np.arange(n) / (0.05 * rate_hz), 0, 1)
    return x * ramp * ramp * (3 - 2 * ramp)


def projection(x: np.ndarray, torque: np.ndarray, frequency_hz: float, rate_hz: float, cycles: float) -> tuple[float, float]:
    """(K', K'') at one frequency: the torque's and the angle's components there over the last
    ``cycles`` whole cycles (whatever else the history holds)."""
    n = int(round(cycles * rate_hz / frequency_hz))
    t = np.arange(x.size)[-n:] / rate_hz
    e = np.exp(-2j * np.pi * frequency_hz * t)
    k = np.mean(torque[-n:] * e) / np.mean(x[-n:] * e)
    return k.real, k.imag


def ramp_hold(coupling, angle: float, ramp_s: float, hold_s: float, rate_hz: float = 2000.0) -> tuple[float, float]:
    """Torques (N*m) at the end of a linear ramp to ``angle`` over ramp_s and after a hold of hold_s."""
    n_r, n_h = int(ramp_s * rate_hz), int(hold_s * rate_hz)
    x = np.r_[angle * np.arange(1, n_r + 1) / n_r, np.full(n_h, angle)]
    torque = coupling.respond(x, 1 / rate_hz)
    return torque[n_r - 1], torque[-1]


def changes_smoothly(values) -> bool:
    """No switch in a sequence sampled at even steps: its second differences stay at most a fifth
    of its largest first difference (a step between two samples would be as large as one)."""
    d1, d2 = np.diff(values), np.diff(values, 2)
    return bool(np.max(np.abs(d2)) <= 0.2 * np.max(np.abs(d1)) + 1e-9 * abs(values[0]))
