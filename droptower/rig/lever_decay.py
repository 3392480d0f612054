"""The lever's free decay on the coupling: the one integrator of J phi'' = T_rest - T(phi).

After the impact the lever (inertia J about the pivot) swings with the coupling torque T as
its only torque but the screw's constant T_rest, the torque the coupling carried at rest (the
preload; 0 without one). phi is the rotation from the rest angle. The coupling's state advances
with the lever, one element step per time step for every row of a batch (rows on several threads),
compiled with the kernels (:func:`droptower.rheology.kernels.step_instance`).

Two schemes, both explicit and far inside their stability limit (dt sqrt(K_max/J) ~ 0.02 at
the rig's step against 2); the coupling's own updates have none:

- ``SYMPLECTIC_EULER``: the angle advances with the old rate, the torque is taken at the angle
  reached, then the rate: exactly what the pymunk scene does (:mod:`droptower.rig.scene`), so
  the plan (:mod:`droptower.rig.predictions`) agrees with the simulation;
- ``VERLET``: velocity Verlet, second order for the elastic torque (first order where the
  core's rate-dependent elements see the step's mean rate): the identification's
  (``droptower.identify.lever``), which compares decays sampled more coarsely than the rig steps.

Torque convention (one for the package): :meth:`LeverDecay.advance` returns the coupling torque
itself, T (what the flange sensor reads, the preload included: the rig's
:func:`droptower.rig.predictions.free_decay`); :func:`torque_from_rest` gives T - T_rest, the
torque that moves the lever and what a pre-trigger baseline leaves of a measured torque (the
identification's ``free_decay``). Both sides compute it here, so they cannot drift apart.

The pymunk scene cannot use this integrator (the impact is pymunk's contact solver); it is
tested against it (``tests/test_rig_scene.py``, ``tests/test_rig_planner.py``).
"""
from __future__ import annotations

import numpy as np
from numba import njit

from droptower.rheology import Coupling, CouplingState
from droptower.rheology import kernels as K
from droptower.rheology.numba_cache import compile_once_across_processes, row_loop_options
from droptower.rheology.threads import run_rows

SYMPLECTIC_EULER = 0
VERLET = 1


def _decay_steps(codes, p_off, s_off, params, state, x_rest, rest, inertia, phi, rate, acc, h, scheme,
                 angle_out, torque_out):
    """Advance every row by angle_out.shape[1] steps; phi, rate, acc (B,) carry the lever from one
    call to the next (in place); angle_out gets phi (rad) and torque_out the coupling torque (N*m)
    at the end of each step."""
    nb, nk = angle_out.shape
    shared = params.shape[0] == 1
    for b in range(nb):
        pb = params[0] if shared else params[b]
        sb = state[b]
        p = phi[b]
        v = rate[b]
        a = acc[b]
        x0 = x_rest[b]
        for k in range(nk):
            # one call of the (inlined, large) coupling step for both schemes: it is compiled once
            if scheme == SYMPLECTIC_EULER:
                p1 = p + h * v
            else:
                p1 = p + h * v + 0.5 * h * h * a
            t = K.step_instance(codes, p_off, s_off, pb, sb, x0 + p, x0 + p1, h)
            if scheme == SYMPLECTIC_EULER:
                v += (rest[b] - t) / inertia[b] * h
            else:
                a_new = (rest[b] - t) / inertia[b]
                v += 0.5 * h * (a + a_new)
                a = a_new
            p = p1
            angle_out[b, k] = p
            torque_out[b, k] = t
        phi[b] = p
        rate[b] = v
        acc[b] = a


# one build: a large batch (the candidates of an identification) runs in chunks of rows on
# threads (droptower.rheology.threads)
_decay_steps = njit(**row_loop_options(__file__), **K.JIT)(_decay_steps)


def torque_from_rest(torque_nm: np.ndarray, rest_torque_nm: np.ndarray) -> np.ndarray:
    """The coupling torque's change from rest, T - T_rest (N*m).

    torque_nm: the coupling torque T, (B,) or (B, N); rest_torque_nm: (B,) the torque the
    coupling carried at rest (the screw's, the preload; 0 without one). The lever feels exactly
    this, since the screw keeps holding T_rest.
    """
    torque = np.asarray(torque_nm, float)
    rest = np.asarray(rest_torque_nm, float)
    return torque - (rest[:, None] if torque.ndim == 2 else rest)


class LeverDecay:
    """A batch of levers decaying on their coupling instances, advanced in chunks of steps.

    coupling: one parameter set, or one per row; state: the coupling's state at rest before the
    impact (advanced in place); inertia_kgm2, rate0_rad_per_s: (B,); rest_torque_nm: the screw's
    torque (B,), by default the state's torque; step_s: the time step (s); scheme: see above.
    """

    def __init__(self, coupling: Coupling, state: CouplingState, inertia_kgm2: np.ndarray,
                 rate0_rad_per_s: np.ndarray, step_s: float, scheme: int,
                 rest_torque_nm: np.ndarray | None = None):
        self.coupling, self.state, self.step_s, self.scheme = coupling, state, float(step_s), int(scheme)
        self.inertia = np.ascontiguousarray(np.broadcast_to(np.asarray(inertia_kgm2, float), (state.batch,)))
        self.rate = np.ascontiguousarray(np.asarray(rate0_rad_per_s, float).copy())
        self.rest = np.ascontiguousarray(state.torque_nm.copy() if rest_torque_nm is None
                                         else np.asarray(rest_torque_nm, float).copy())
        self.x_rest = state.angle_rad.copy()
        self.phi = np.zeros(state.batch)
        self.acc = np.zeros(state.batch)

    def rows(self, keep: np.ndarray) -> "LeverDecay":
        """The levers ``keep`` (a boolean mask of the batch), to be advanced on from where they are:
        their coupling rows, state, rest torque and carried angle, rate and acceleration (copies)."""
        c, s = self.coupling, self.state
        coupling = c.with_params(c.params[keep]) if c.n_sets > 1 else c
        sub = LeverDecay(coupling, s.take(keep),
                         self.inertia[keep], self.rate[keep], self.step_s, self.scheme, rest_torque_nm=self.rest[keep])
        sub.x_rest, sub.phi, sub.acc = self.x_rest[keep], self.phi[keep], self.acc[keep]
        return sub

    def torque_from_rest(self, torque_nm: np.ndarray) -> np.ndarray:
        """T - T_rest (N*m) of torques :meth:`advance` returned for these levers (B, N)."""
        return torque_from_rest(torque_nm, self.rest)

    def advance(self, n_steps: int) -> tuple[np.ndarray, np.ndarray]:
        """The next ``n_steps`` steps: rotation from rest (rad) and the coupling torque T itself
        (N*m, the preload included; :meth:`torque_from_rest` for T - T_rest), each (B, n_steps)."""
        c, s = self.coupling, self.state
        angle = np.empty((s.batch, n_steps))
        torque = np.empty((s.batch, n_steps))
        # the arguments at positions 3-10 and 13-14 have one row per row of the batch (params unless shared)
        run_rows(_decay_steps, (c.codes, c.p_off, c.s_off, c.params, s.values, self.x_rest, self.rest, self.inertia,
                                self.phi, self.rate, self.acc, self.step_s, self.scheme, angle, torque),
                 (3, 4, 5, 6, 7, 8, 9, 10, 13, 14), s.batch)
        if n_steps:
            s.angle_rad[...] = self.x_rest + self.phi
            s.torque_nm[...] = torque[:, -1]
        return angle, torque

compile_once_across_processes(globals())  # a kernel no cache holds is compiled by one process at a time
