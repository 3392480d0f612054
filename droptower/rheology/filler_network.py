"""Per-step update of the ``filler_network`` element: the Payne effect of filled rubber from
state variables that mean the same in any history.

Two mechanisms, each with its own state (Iwan 1966; Masing 1926; Kraus 1984; Lion 1997 and
Höfer & Lion 2009 for a filler structure that breaks down with the strain and re-forms in time):

- **Friction between filler clusters**: an Iwan network of n Jenkins elements (spring k_i in
  series with a Coulomb slider that slips at the elongation a_i), the yield angles a_i
  distributed log-logistically about ``critical_angle``. Its state: the springs' elongations
  e_i (rad). It gives the amplitude-dependent storage stiffness and a rate-independent loss
  with Masing's rules (small loops on a large one see the sticking, stiff springs); the torque
  is continuous in the angle, whatever the history.
- **Structure of the filler network**: the fraction g in (0, 1] of the network that is intact
  (its springs and slider limits scale with g; the yield angles do not). Its state: the damage
  1 - g and the elongation about a slowly moving centre, e_c (rad), de_c/dt = dx/dt - e_c /
  ``centre_relaxation_time`` (the network re-forms about a held mean angle, a preload). The
  network breaks down at once to g_eq(|e_c|) = 1 / (1 + (|e_c| / breakdown_angle)^(2 m)) when
  the elongation grows (rate-independent, like a Mullins or Payne breakdown), and recovers
  towards 1 with ``recovery_time`` (seconds to minutes): dg/dt = (1 - g) / recovery_time while
  g < g_eq. The Payne softening is thus remembered after a large amplitude, recovers smoothly,
  and a small tone on a large one sees the network the large one broke down.

Energy (exact to round-off for the trapezoidal work ½ (T0 + T1) dx the core books): the
Iwan springs store g Σ ½ k_i e_i², the sliders dissipate their mean force times their slip.
Breakdown lowers g at fixed elongations (stored energy is released, dissipated: fracture of
filler-filler bonds); it is booked at the end of a step only where that step's balance stays
non-negative, else one step later. Recovery re-forms bonds unstrained: the elongations are
scaled by g_old / g_new so the torque is kept while the stored energy falls. So the element is
passive for any history and step, with no stability limit (the slider update is a return
mapping, the centre's relaxation exact for the step's constant rate).

params: [n, breakdown_angle, 2 m, recovery_time, centre_relaxation_time, k_1..k_n, f_1..f_n]
(f_i = k_i a_i, the slider limits of the intact network).
internal (after the common header): [damage 1 - g, e_c, cached h, exp(-h/recovery_time),
exp(-h/centre_relaxation_time), centre_relaxation_time (1 - exp(-h/...)) / h, e_1..e_n,
n scratch slots].
"""
from __future__ import annotations

import numpy as np
from numba import njit

from droptower.rheology.kernels import JIT, _bank_commit, _bank_coulomb

HEADER_PARAMS = 5
N_INTERNAL_FIXED = 6  # damage, e_c, h, two exponentials, the centre's ramp factor


@njit(**JIT)
def filler_network(p, po, s, so, x0, x1, h):
    """One step of the filler network from x0 to x1 (rad) over h (s); returns its torque (N*m)."""
    n = int(p[po])
    breakdown_angle = p[po + 1]
    two_m = p[po + 2]
    if s[so + 5] != h:  # exponentials only when the step changes
        tau_c = p[po + 4]
        s[so + 5] = h
        s[so + 6] = np.exp(-h / p[po + 3])
        s[so + 7] = np.exp(-h / tau_c)
        s[so + 8] = -tau_c * np.expm1(-h / tau_c) / h  # expm1: exact also for h << tau_c
    dx = x1 - x0
    damage0 = s[so + 3]
    g0 = 1.0 - damage0
    centre_elongation = s[so + 4] * s[so + 7] + dx * s[so + 8]
    # recovery towards the intact network, then breakdown by the elongation about the centre
    g_target = min(1.0 - damage0 * s[so + 6], 1.0 / (1.0 + (abs(centre_elongation) / breakdown_angle) ** two_m))
    eo = so + 3 + N_INTERNAL_FIXED
    elong = s[eo:eo + n]
    ks = p[po + HEADER_PARAMS:po + HEADER_PARAMS + n]
    stored0 = s[so + 0]
    torque0 = s[so + 2]
    if g_target > g0:
        # re-formed bonds are unstrained: the torque g k e is kept, the stored energy falls
        ratio = g0 / g_target
        for i in range(n):
            elong[i] *= ratio
    _bank_coulomb(ks, p[po + HEADER_PARAMS + n:po + HEADER_PARAMS + 2 * n], elong, s[eo + n:eo + 2 * n], n, dx)
    force, energy, _ = _bank_commit(ks, elong, s[eo + n:eo + 2 * n], n, dx)
    g = g_target
    if g < g0 and 0.5 * (torque0 + g * force) * dx - (g * energy - stored0) < 0.0:
        g = g0  # this step cannot book the breakdown with a non-negative balance: the next one will
    torque1 = g * force
    stored1 = g * energy
    s[so + 1] += 0.5 * (torque0 + torque1) * dx - (stored1 - stored0)
    s[so + 0] = stored1
    s[so + 2] = torque1
    s[so + 3] = 1.0 - g
    s[so + 4] = centre_elongation
    return torque1


def max_tangent_stiffness(params: np.ndarray) -> float:
    """Upper bound of the element's tangent stiffness (N*m/rad): every spring of the intact
    network sticking (g <= 1)."""
    n = int(params[0])
    return float(np.sum(params[HEADER_PARAMS:HEADER_PARAMS + n]))


def max_damping(params: np.ndarray) -> float:
    """The element has no viscous part (N*m*s/rad)."""
    return 0.0
