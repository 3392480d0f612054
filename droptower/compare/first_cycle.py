"""What a first-cycle decay fit reads on a coupling whose loss and stiffness change with the amplitude.

The drop tower reads each decay with one damped cosine over its first cycle (Rapp et al. 2022,
eq. 13-16): d = E_diss / E_el = 1/2 ((A_0 / A_1)^2 - 1), A_0 and A_1 the envelope at the start and
the end of the cycle. The servo bench reads the steady loop at one amplitude. On a coupling
whose loss grows with the amplitude and whose stiffness falls with it (filled rubber: the
Payne effect) the two differ even where the model holds exactly, because the first cycle spans
amplitudes about a factor 2 apart (docs/theory.md#first-cycle). This module predicts the
first-cycle reading from the coupling's own steady loops over the amplitudes the cycle spans:
the energy balance of a slowly decaying oscillation, each cycle losing the energy of the steady
loop at its amplitude,

    dE/dn = -W(A),  E(A) = 1/2 K'(A) A^2,  W(A) = pi K''(A) A^2,

integrated over one cycle (n from 0 to 1) from the reading's A_0. Since the energy is spent
through a stiffness that changes with the amplitude, (A_0 / A_1)^2 = (E_0 / E_1) K'(A_1) / K'(A_0):
a coupling that stiffens as the amplitude falls (the Payne effect) reads a larger d than its
loop at the window's middle even where the cycle loses just that loop's energy. It holds no slow relaxation:
a branch relaxing below the decay's frequency adds a creep mode the fit reads as decay
(docs/theory.md#first-cycle), which a linear model of that branch measures separately.
"""
from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from droptower.errors import DroptowerError
from droptower.rheology import Coupling
from droptower.servo.steady import steady_state

#: the amplitudes (fractions of the cycle's start amplitude) whose steady loops are evaluated:
#: the cycle ends above 0.2 A_0 for any reading below d = 12 (A_0 / A_1 = (1 + 2 d)^(1/2))
SPAN = (0.2, 1.0)
#: steady loops per decay over SPAN (log-spaced; K' and K'' interpolated linearly in log A between them)
LOOPS = 9
#: integration points of the energy balance over SPAN
FINE = 2000


def loop_span_damping_ratio(coupling: Coupling, start_amplitude_rad: ArrayLike, frequency_hz: ArrayLike, *,
                            loops: int = LOOPS, cycles: int = 2) -> np.ndarray:
    """The damping ratio d a first-cycle fit reads on a decay that loses, in each cycle, the
    energy of the coupling's steady loop at its amplitude (module docstring).

    Parameters
    ----------
    coupling
        The coupling.
    start_amplitude_rad
        The envelope's amplitude at the start of the first cycle (rad), shape (B,).
    frequency_hz
        The decay's frequency (Hz), broadcast to (B,): the steady loops are taken at it.
    loops, cycles
        Steady loops per decay over SPAN of the start amplitude; cycles run in and evaluated per loop.

    Returns
    -------
    numpy.ndarray
        d = 1/2 ((A_0 / A_1)^2 - 1) (-), shape (B,), A_1 the amplitude after one cycle of the energy balance.
    """
    a0 = np.atleast_1d(np.asarray(start_amplitude_rad, float))
    freq = np.broadcast_to(np.asarray(frequency_hz, float), a0.shape)
    if not (np.all(np.isfinite(a0)) and np.all(a0 > 0) and np.all(np.isfinite(freq)) and np.all(freq > 0)):
        raise DroptowerError("first-cycle prediction: start amplitudes and frequencies must be positive and finite")
    grid = np.geomspace(*SPAN, loops)
    ss = steady_state(coupling, (a0[:, None] * grid).ravel(), np.repeat(freq, loops), cycles=cycles,
                      run_in_cycles=cycles)
    storage = ss.storage_stiffness_nm_per_rad.reshape(a0.size, loops)
    loss = ss.loss_stiffness_nm_per_rad.reshape(a0.size, loops)
    fine = np.geomspace(SPAN[1], SPAN[0], FINE)  # from the start amplitude downwards
    out = np.empty(a0.size)
    for i in range(a0.size):
        amp = a0[i] * fine
        k1 = np.interp(np.log(fine), np.log(grid), storage[i])
        k2 = np.interp(np.log(fine), np.log(grid), loss[i])
        energy = 0.5 * k1 * amp ** 2
        if np.any(k2 <= 0) or np.any(np.diff(energy) >= 0):
            raise DroptowerError(f"first-cycle prediction: the steady loops at {np.degrees(a0[i]):.3g} deg, "
                                 f"{freq[i]:.3g} Hz do not lose energy or do not store less at smaller amplitudes")
        # cycles elapsed from A_0 down to each amplitude: dn = -dE / W
        rate = 1.0 / (np.pi * k2 * amp ** 2)
        cycles_done = np.concatenate([[0.0], np.cumsum(0.5 * (rate[1:] + rate[:-1]) * -np.diff(energy))])
        if cycles_done[-1] < 1.0:
            raise DroptowerError(f"first-cycle prediction: at {np.degrees(a0[i]):.3g} deg, {freq[i]:.3g} Hz the "
                                 f"first cycle ends below {SPAN[0]} of its start amplitude (d above 12)")
        a1 = np.exp(np.interp(1.0, cycles_done, np.log(amp)))
        out[i] = 0.5 * ((a0[i] / a1) ** 2 - 1.0)
    return out

