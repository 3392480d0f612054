"""The lever's free decay after the impact, with the coupling as its only torque.

J phi'' + T(phi, history) = 0, phi(0) = 0, phi'(0) = the rate the impact gave the lever. The
coupling's state advances with the lever for every row (a test under one parameter set), so all
tests of all candidate parameter sets decay in one call. The integrator is the rig's
(:mod:`droptower.rig.lever_decay`), with velocity Verlet: second order for the elastic torque (first
order where the core's rate-dependent elements see the step's mean rate: 0.1 % of the peak at
38.4 kHz, tested); the rig's pymunk scene integrates the same equation with symplectic Euler at
the same step, and the two agree far below the fit errors that matter (tested).

Each row runs only as many steps as it asks for (``n_steps`` per row): a campaign's decays end
at a few periods of their own, and the light lever's period is about half the heavy one's, so
running every row to the longest end spends a quarter of the steps on samples nobody compares.
The rows are advanced together up to the first end, the rows still running on to the next,
and so on (the rig's integrator carries each row's lever and coupling state from one call to
the next), so a row's history is the one a single call of its own length gives.
"""
from __future__ import annotations

import numpy as np

from droptower.rheology import Coupling, CouplingState
from droptower.rig.lever_decay import VERLET, LeverDecay


def free_decay(coupling: Coupling, inertia_kgm2: np.ndarray, rate0_rad_per_s: np.ndarray, n_steps: int | np.ndarray,
               step_s: float, state: CouplingState | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Angle (rad) and coupling torque (N*m) of the free decay on the grid k * step_s, k = 0..n_steps.

    coupling: one parameter set, or one per row (``coupling.n_sets == B``); inertia_kgm2,
    rate0_rad_per_s: (B,); n_steps: the steps of every row, or of each row (B,); state: the
    coupling's state at rest before the impact (default virgin), advanced in place (each row to
    its own end). Angle and torque are changes from that rest (the screw holding a preload
    keeps its torque, so the lever feels T - T_rest). Returns two (B, max(n_steps) + 1) arrays;
    a row that ends earlier holds its last values.
    """
    rate0 = np.asarray(rate0_rad_per_s, dtype=float)
    b = rate0.size
    state = coupling.new_state(b) if state is None else state
    steps = np.broadcast_to(np.asarray(n_steps, dtype=np.int64), (b,))
    if b and steps.min() < 0:
        raise ValueError("n_steps must be >= 0")
    total = int(steps.max()) if b else 0
    angle = np.zeros((b, total + 1))
    torque = np.zeros((b, total + 1))
    if b == 0:
        return angle, torque
    running = np.arange(b)  # the rows the lever advances (all, then those not ended yet)
    lever = LeverDecay(coupling, state, inertia_kgm2, rate0, step_s, VERLET)
    done = 0
    for end in map(int, np.unique(steps)):
        if end > done:
            a, q = lever.advance(end - done)
            angle[running, done + 1:end + 1] = a
            torque[running, done + 1:end + 1] = lever.torque_from_rest(q)  # the convention of rig.lever_decay
            done = end
        ended = steps[running] == end
        rows = running[ended]
        angle[rows, end + 1:] = angle[rows, end][:, None]
        torque[rows, end + 1:] = torque[rows, end][:, None]
        if lever.state is not state:  # a subset's copy: its rows' states back into the caller's
            state.merge(running, lever.state)
        running = running[~ended]
        if not running.size:
            break
        if ended.any():
            lever = lever.rows(~ended)
    return angle, torque


def at_times(history: np.ndarray, step_s: float, times_s: np.ndarray) -> np.ndarray:
    """``history`` (B, K) on the grid k * step_s, linearly interpolated at ``times_s`` (B, N) (s)."""
    pos = np.clip(times_s / step_s, 0.0, history.shape[1] - 1.000001)
    lo = pos.astype(np.int64)
    frac = pos - lo
    a = np.take_along_axis(history, lo, axis=1)
    c = np.take_along_axis(history, lo + 1, axis=1)
    return a + frac * (c - a)
