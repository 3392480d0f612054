"""Data for the identification tests: the virtual servo bench's histories driven through the
core with known parameters, plus white measurement noise (no tests in this module)."""
from __future__ import annotations

import numpy as np

from droptower.identify.data import Segment, make_segment
from droptower.rheology import Coupling, parse_coupling
from droptower.servo import histories as H

FS = 512.0  # Hz: 25 samples per cycle at 20 Hz, enough for the lab evaluation of the blocks
D = np.radians


def coupling(*elements: dict) -> Coupling:
    return parse_coupling({"name": "truth", "element": list(elements)})


def fitting_histories(fs: float = FS) -> dict[str, H.History]:
    """The zero-dimensional model paper's test types: slow ramps, a preloaded sine, frequency and amplitude sweeps, steps."""
    return {
        "ramps": H.ramps(D(3.0), D(1.0), fs),
        "preload": H.sine(5.0, D(1.0), fs, offset_rad=D(2.0), run_in_cycles=10, cycles=10),
        "frequency_sweep": H.frequency_sweep([2.0, 5.0, 10.0, 20.0], D(1.0), fs, run_in_cycles=4, cycles=4),
        "amplitude_sweep": H.amplitude_sweep(D(np.array([0.3, 1.0, 2.5])), 10.0, fs, run_in_cycles=4, cycles=4),
        "steps": H.steps(D(np.array([1.5, -1.0, 0.0])), fs, hold_s=1.0, rise_s=0.02),
    }


def random_history(fs: float = FS, seed: int = 3, duration_s: float = 8.0) -> dict[str, H.History]:
    """The zero-dimensional model paper's validation test: a band-limited random profile."""
    return {"random": H.random_profile(D(1.0), (0.5, 20.0), duration_s, fs, seed=seed)}


def records(truth: Coupling, histories: dict[str, H.History], noise: float = 0.005, seed: int = 0
            ) -> tuple[list[Segment], float]:
    """Segments of ``truth``'s torque with white noise of ``noise`` times the largest |torque|;
    returns them and the noise standard deviation (N*m)."""
    rng = np.random.default_rng(seed + 1000)  # never the random profile's own generator
    torques = {k: truth.respond(h.angle_rad, h.dt_s) for k, h in histories.items()}
    sigma = noise * max(float(np.max(np.abs(t))) for t in torques.values())
    segs = [make_segment(h.time_s, h.angle_rad, torques[k] + rng.normal(0.0, sigma, torques[k].size), name=k)
            for k, h in histories.items()]
    return segs, sigma
