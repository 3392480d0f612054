"""The preload: a static pre-twist of the coupling, set by a screw on the lever before the drop.

Rapp et al. 2022 (Table 1, "Experimental Setup"): "by applying a force on the lever arm using a screw,
the coupling can be pre-deformed prior to the experiment" (0, 0.5, 1 kN*m). Here the screw
turns the lever slowly (a smooth quasi-static ramp over ``ramp_s``) to the twist at which the
coupling, after a conditioning oscillation of decreasing amplitude about the twist and a hold
of ``hold_s`` in which its rate-dependent parts relax, carries the preload torque. The twist is found by bracketing and regula falsi (Illinois) on the held
torque, which rises monotonically with the twist; all conditions of a batch are solved at once.
During the test the screw keeps its torque constant and the lever oscillates about the twist.
A positive preload twists the coupling in the direction the impact turns the lever.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from droptower.configs import display_name
from droptower.errors import DroptowerError
from droptower.rheology import Coupling, CouplingState

RAMP_STEPS = 200
HOLD_STEPS = 200
SETTLE_STEPS = 100          # last stretch of the hold, at a fine step (the test's time scale)
SETTLE_STEP_S = 1e-4
TOLERANCE = 1e-9            # relative torque error of the twist
MAX_ITER = 80
# Conditioning at the twist (as Rapp et al.'s (2022) pre-straining: "~100 cycles with amplitude decreasing
# to zero"): an oscillation about the twist whose amplitude falls to zero wipes the friction
# elements' memory of the ramp, so the preload leaves no residual friction torque that the
# first swings after the impact would release (Rapp et al. 2022, Fig. 11: no influence of the preload).
CONDITIONING_CYCLES = 20
CONDITIONING_AMPLITUDE_RAD = np.deg2rad(5.0)
CONDITIONING_FREQUENCY_HZ = 2.0
CONDITIONING_STEPS_PER_CYCLE = 100


@dataclass
class Pretwist:
    """Coupling state after the preload: angle_rad (B,) the twist; torque_nm (B,) the torque the
    coupling carries there (the screw's torque); state: the coupling state, ready for the test."""

    angle_rad: np.ndarray
    torque_nm: np.ndarray
    state: CouplingState

    def take(self, rows: np.ndarray) -> "Pretwist":
        """The pretwist of some rows of the batch (copies)."""
        return Pretwist(self.angle_rad[rows], self.torque_nm[rows], self.state.take(rows))


def _history(angle_end: np.ndarray, ramp_s: float, hold_s: float) -> tuple[np.ndarray, float, float]:
    s = np.arange(1, RAMP_STEPS + 1) / RAMP_STEPS
    smooth = s * s * (3.0 - 2.0 * s)  # smoothstep: the ramp starts and ends at rest
    return angle_end[:, None] * smooth[None, :], ramp_s / RAMP_STEPS, hold_s / HOLD_STEPS


def _conditioning(angle_end: np.ndarray) -> tuple[np.ndarray, float]:
    """Oscillation about the twist with an amplitude falling linearly to zero."""
    n = CONDITIONING_CYCLES * CONDITIONING_STEPS_PER_CYCLE
    phase = np.arange(1, n + 1) / CONDITIONING_STEPS_PER_CYCLE
    wave = CONDITIONING_AMPLITUDE_RAD * (1.0 - phase / CONDITIONING_CYCLES) * np.sin(2 * np.pi * phase)
    return angle_end[:, None] + wave[None, :], 1.0 / (CONDITIONING_FREQUENCY_HZ * CONDITIONING_STEPS_PER_CYCLE)


def hold_at(coupling: Coupling, angle_end: np.ndarray, ramp_s: float, hold_s: float) -> CouplingState:
    """Ramp from a virgin state to ``angle_end`` (one twist per row of the batch), condition and
    hold; returns the state at the end. Rows may be parameter sets of a stacked coupling."""
    ramp, dt_ramp, dt_hold = _history(angle_end, ramp_s, hold_s)
    state = coupling.new_state(angle_end.size)
    coupling.simulate(ramp, dt_ramp, state)
    coupling.simulate(*_conditioning(angle_end), state)  # every row alike, so batches equal single runs
    hold_coarse = np.repeat(angle_end[:, None], HOLD_STEPS, axis=1)
    coupling.simulate(hold_coarse, dt_hold, state)
    coupling.simulate(hold_coarse[:, :SETTLE_STEPS], SETTLE_STEP_S, state)
    return state


def pretwist(coupling: Coupling, preload_nm: np.ndarray, ramp_s: float, hold_s: float) -> Pretwist:
    """Twist each coupling of the batch quasi-statically until it holds ``preload_nm`` (B,).

    Equal preloads are solved once (the twist depends on the coupling and the preload only).
    """
    preload = np.asarray(preload_nm, float).ravel()
    target, inverse = np.unique(preload, return_inverse=True)
    angle = np.zeros(target.size)
    active = target != 0.0
    if np.any(active):
        angle[active] = _solve(coupling, target[active], ramp_s, hold_s)
    state = hold_at(coupling, angle, ramp_s, hold_s)
    full = state.take(inverse)  # each distinct preload's state, once per row that asked for it
    return Pretwist(angle_rad=angle[inverse], torque_nm=full.torque_nm.copy(), state=full)


def _solve(coupling: Coupling, tgt: np.ndarray, ramp_s: float, hold_s: float) -> np.ndarray:
    """Twists (rad) at which the held torque equals ``tgt`` (N*m, all non-zero)."""

    def held(x):
        return hold_at(coupling, x, ramp_s, hold_s).torque_nm - tgt

    # bracket: start from the stiffest guess (too small a twist), double until the torque passes
    lo = np.zeros(tgt.size)
    f_lo = -tgt.copy()
    shortest_step = min(ramp_s / RAMP_STEPS, hold_s / HOLD_STEPS, SETTLE_STEP_S,
                        1.0 / (CONDITIONING_FREQUENCY_HZ * CONDITIONING_STEPS_PER_CYCLE))
    hi = tgt / max(coupling.max_tangent_stiffness(0.0, step_s=shortest_step), 1e-12)
    f_hi = held(hi)
    for _ in range(60):
        low = np.sign(f_hi) == np.sign(f_lo)
        if not np.any(low):
            break
        lo = np.where(low, hi, lo)
        f_lo = np.where(low, f_hi, f_lo)
        hi = np.where(low, 2.0 * hi, hi)
        f_hi = np.where(low, held(hi), f_hi)
    else:
        raise DroptowerError(f"the coupling cannot hold the preload {np.abs(tgt).max():g} N*m after a hold of "
                             f"{hold_s} s (it has no static stiffness)", file=display_name(coupling.path, "couplings") or coupling.name)
    # Illinois regula falsi, vectorised
    side = np.zeros(tgt.size)
    x = hi
    for _ in range(MAX_ITER):
        x = (lo * f_hi - hi * f_lo) / (f_hi - f_lo)
        f = held(x)
        if np.all(np.abs(f) <= TOLERANCE * np.abs(tgt)):
            break
        same_hi = np.sign(f) == np.sign(f_hi)
        f_lo = np.where(same_hi & (side == 1), f_lo / 2, f_lo)
        f_hi = np.where(~same_hi & (side == -1), f_hi / 2, f_hi)
        lo = np.where(same_hi, lo, x)
        f_lo = np.where(same_hi, f_lo, f)
        hi = np.where(same_hi, x, hi)
        f_hi = np.where(same_hi, f, f_hi)
        side = np.where(same_hi, 1, -1)
    return x
