"""The lever's free decay after the impact, with the coupling as its only torque (NOTES §1.3).

J phi'' + T(phi, history) = 0, phi(0) = 0, phi'(0) = the rate the impact gave the lever. The
coupling T is the rheological core: its state advances with the lever, one batched
:meth:`Coupling.step` per time step for every row (a test under one parameter set), so all
tests of all candidate parameter sets decay in one call. Integration: velocity Verlet
(explicit; second order for the elastic torque, first order where the core's rate-dependent
elements see the step's mean rate: 0.1 % of the peak at 38.4 kHz, tested) on a step: the lever's highest
frequency sqrt(K_max / J) times the step is ~0.02 at the rig's sample rate, far inside the
scheme's stability limit 2, and the core's own updates (exact for the Maxwell branches,
implicit for the sliders) have no stability limit. The rig (pymunk, ``droptower.rig``)
integrates the same equation with symplectic Euler at the same step; the two agree far
below the fit errors that matter (tested).
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange

from droptower.rheology import Coupling, CouplingState
from droptower.rheology import kernels as K


def _free_decay(codes, p_off, s_off, params, state, x_start, rest, inertia, rate0, h, angle_out, torque_out):
    """Every row's lever decays on its own coupling instance (rows in parallel)."""
    nb, nk = angle_out.shape
    shared = params.shape[0] == 1
    for b in prange(nb):
        pb = params[0] if shared else params[b]
        sb = state[b]
        x0 = x_start[b]
        phi = x0
        v = rate0[b]
        acc = 0.0
        angle_out[b, 0] = 0.0
        torque_out[b, 0] = 0.0
        for k in range(1, nk):
            x1 = phi + h * v + 0.5 * h * h * acc
            t = K.step_instance(codes, p_off, s_off, pb, sb, phi, x1, h) - rest[b]
            acc_new = -t / inertia[b]
            v += 0.5 * h * (acc + acc_new)
            acc = acc_new
            phi = x1
            angle_out[b, k] = phi - x0
            torque_out[b, k] = t


_free_decay_parallel = njit(parallel=True, **K.JIT)(_free_decay)  # the project's cache guard


def free_decay(coupling: Coupling, inertia_kgm2: np.ndarray, rate0_rad_per_s: np.ndarray, n_steps: int,
               step_s: float, state: CouplingState | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Angle (rad) and coupling torque (N*m) of the free decay on the grid k * step_s, k = 0..n_steps.

    coupling: one parameter set, or one per row (``coupling.n_sets == B``); inertia_kgm2,
    rate0_rad_per_s: (B,); state: the coupling's state at rest before the impact (default
    virgin), advanced in place. Angle and torque are changes from that rest (the screw holding
    a preload keeps its torque, so the lever feels T - T_rest). Returns two (B, n_steps + 1) arrays.
    """
    inertia = np.ascontiguousarray(inertia_kgm2, dtype=float)
    rate0 = np.ascontiguousarray(rate0_rad_per_s, dtype=float)
    b = rate0.size
    state = coupling.new_state(b) if state is None else state
    angle = np.empty((b, n_steps + 1))
    torque = np.empty((b, n_steps + 1))
    _free_decay_parallel(coupling.codes, coupling.p_off, coupling.s_off, coupling.params, state.values,
                         state.angle_rad.copy(), state.torque_nm.copy(), inertia, rate0, float(step_s), angle, torque)
    state.angle_rad[...] += angle[:, -1]
    state.torque_nm[...] += torque[:, -1]
    return angle, torque


def at_times(history: np.ndarray, step_s: float, times_s: np.ndarray) -> np.ndarray:
    """``history`` (B, K) on the grid k * step_s, linearly interpolated at ``times_s`` (B, N) (s)."""
    pos = np.clip(times_s / step_s, 0.0, history.shape[1] - 1.000001)
    lo = pos.astype(np.int64)
    frac = pos - lo
    a = np.take_along_axis(history, lo, axis=1)
    c = np.take_along_axis(history, lo + 1, axis=1)
    return a + frac * (c - a)
