"""The lever's free decay after the impact, with the coupling as its only torque.

J phi'' + T(phi, history) = 0, phi(0) = 0, phi'(0) = the rate the impact gave the lever. The
coupling's state advances with the lever for every row (a test under one parameter set), so all
tests of all candidate parameter sets decay in one call. The integrator is the rig's
(:mod:`droptower.rig.lever`), with velocity Verlet: second order for the elastic torque (first
order where the core's rate-dependent elements see the step's mean rate: 0.1 % of the peak at
38.4 kHz, tested); the rig's pymunk scene integrates the same equation with symplectic Euler at
the same step, and the two agree far below the fit errors that matter (tested).
"""
from __future__ import annotations

import numpy as np

from droptower.rheology import Coupling, CouplingState
from droptower.rig.lever import VERLET, LeverDecay


def free_decay(coupling: Coupling, inertia_kgm2: np.ndarray, rate0_rad_per_s: np.ndarray, n_steps: int,
               step_s: float, state: CouplingState | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Angle (rad) and coupling torque (N*m) of the free decay on the grid k * step_s, k = 0..n_steps.

    coupling: one parameter set, or one per row (``coupling.n_sets == B``); inertia_kgm2,
    rate0_rad_per_s: (B,); state: the coupling's state at rest before the impact (default
    virgin), advanced in place. Angle and torque are changes from that rest (the screw holding
    a preload keeps its torque, so the lever feels T - T_rest). Returns two (B, n_steps + 1) arrays.
    """
    rate0 = np.asarray(rate0_rad_per_s, dtype=float)
    state = coupling.new_state(rate0.size) if state is None else state
    lever = LeverDecay(coupling, state, inertia_kgm2, rate0, step_s, VERLET)
    angle, torque = lever.advance(n_steps)
    zero = np.zeros((rate0.size, 1))
    return np.hstack([zero, angle]), np.hstack([zero, torque - lever.rest[:, None]])


def at_times(history: np.ndarray, step_s: float, times_s: np.ndarray) -> np.ndarray:
    """``history`` (B, K) on the grid k * step_s, linearly interpolated at ``times_s`` (B, N) (s)."""
    pos = np.clip(times_s / step_s, 0.0, history.shape[1] - 1.000001)
    lo = pos.astype(np.int64)
    frac = pos - lo
    a = np.take_along_axis(history, lo, axis=1)
    c = np.take_along_axis(history, lo + 1, axis=1)
    return a + frac * (c - a)
