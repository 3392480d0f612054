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
  and a small tone on a large one sees the network the large one broke down. The network's
  stress relaxes about its rest state with the centre's time (the elongations e_i decay as
  exp(-t / centre_relaxation_time) besides their motion): a held twist, a preload, leaves no
  strained friction elements behind.

Energy (exact to round-off for the trapezoidal work ½ (T0 + T1) dx the core books): the
Iwan springs store g Σ ½ k_i e_i², the sliders dissipate their mean force times their slip.
Breakdown lowers g at fixed elongations (stored energy is released, dissipated: fracture of
filler-filler bonds); it is booked at the end of a step only where that step's balance stays
non-negative, else one step later. Recovery re-forms bonds unstrained: the elongations are
scaled by g_old / g_new so the torque is kept while the stored energy falls. So the element is
passive for any history and step, with no stability limit (the slider update is a return
mapping, the centre's relaxation exact for the step's constant rate).

params: [n, breakdown_angle, 2 m, recovery_time, centre_relaxation_time, k_1..k_n, a_1..a_n]
(the intact network's spring stiffnesses and the yield angles).
internal (after the common header): [damage 1 - g, e_c, cached h, exp(-h/recovery_time),
exp(-h/centre_relaxation_time), centre_relaxation_time (1 - exp(-h/...)) / h, a cap of g and
the elongation below which nothing breaks while g <= cap, e_1..e_n].

The sliders' return mapping is that of a Coulomb slider bank (:func:`kernels.slider_bank`),
fused here with the recovery's rescaling and the sums in one vectorised pass.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from droptower.rheology.kernels import CACHE, JIT

HEADER_PARAMS = 5
N_INTERNAL_FIXED = 8  # damage, e_c, h, two exponentials, the centre's ramp factor, g cap, its threshold
#: the breakdown threshold is cached for an intact fraction this share of the damage above the
#: current one (a power per renewal instead of one per step; the result is the same)
THRESHOLD_CAP = 0.01


@njit(cache=CACHE, nogil=True, error_model="numpy", fastmath={"reassoc"})  # vectorised sums
def _sliders(ks, yield_angles, elong, n, ratio, dx):
    """Scale the elongations by ``ratio`` (recovery), move them by dx and clip them to the yield
    angles (Coulomb return mapping); return the force and stored energy of the springs k_i e_i."""
    force = 0.0
    energy = 0.0
    for i in range(n):
        lim = yield_angles[i]
        e = min(max(elong[i] * ratio + dx, -lim), lim)
        elong[i] = e
        force += ks[i] * e
        energy += ks[i] * e * e
    return force, 0.5 * energy


@njit(inline="always", **JIT)
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
    # recovery towards the intact network, then breakdown by the elongation about the centre:
    # g = min(g_rec, g_eq(|e_c|)). g_eq(|e_c|) >= g_rec below the elongation where g_eq equals
    # g_rec; that elongation falls as g_rec rises, so the one of a cap above g_rec bounds it
    g_rec = 1.0 - damage0 * s[so + 6]
    if g_rec > s[so + 9]:
        cap = g_rec + THRESHOLD_CAP * damage0
        s[so + 9] = cap
        s[so + 10] = breakdown_angle * (1.0 / cap - 1.0) ** (1.0 / two_m) if cap < 1.0 else 0.0
    elongation = abs(centre_elongation)
    g_target = g_rec
    if elongation > s[so + 10]:
        g_target = min(g_rec, 1.0 / (1.0 + (elongation / breakdown_angle) ** two_m))
    eo = so + 3 + N_INTERNAL_FIXED
    stored0 = s[so + 0]
    torque0 = s[so + 2]
    # the network's stress relaxes about its rest state like the centre (a held twist becomes
    # unstrained): the elongations shrink by exp(-h/centre_relaxation_time) at the start of the
    # step; the booked trapezoid adds (1 - relax) torque0 dx / 2 to the energy it releases, so
    # it is skipped in a step where that sum would be negative (a large step against the torque)
    relax = s[so + 7]
    if stored0 * (1.0 - relax * relax) + 0.5 * torque0 * (1.0 - relax) * dx < 0.0:
        relax = 1.0
    # recovery: re-formed bonds are unstrained, so the elongations shrink by g0 / g (the torque
    # g k e is kept, the stored energy falls) before the step's motion
    ratio = relax * (g0 / g_target if g_target > g0 else 1.0)
    force, energy = _sliders(p[po + HEADER_PARAMS:po + HEADER_PARAMS + n],
                             p[po + HEADER_PARAMS + n:po + HEADER_PARAMS + 2 * n], s[eo:eo + n], n, ratio, dx)
    g = g_target
    if g < g0 and 0.5 * (relax * torque0 + g * force) * dx - (g * energy - relax * relax * stored0) < 0.0:
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


