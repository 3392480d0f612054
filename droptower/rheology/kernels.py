"""Compiled per-step updates of the elementary rheological elements.

Every coupling is compiled (see :mod:`droptower.rheology.elements`) into a flat list of
*kernel elements*. A kernel element owns a slice of a parameter vector and a slice of a state
vector; it advances one time step from the committed angle ``x0`` to the trial angle ``x1``
over ``h`` seconds (the angle varies linearly in between) and returns its torque at the end of
the step.

State layout of every kernel element (SI units)::

    state[0]  stored energy at the end of the step            (J)
    state[1]  energy dissipated since the state was created   (J)
    state[2]  the element's torque at the end of the step     (N*m)
    state[3:] internal variables (spring elongations)         (rad)

Updates are exact (exponential) for the linear relaxation elements and implicit for the
stiff ones, so none of them has a stability limit on ``h``. Dissipation is accounted
physically: the force on each dashpot or slider, averaged over the step (trapezoidal), times
its stroke in the step. For elements whose torque is a spring force in series with the
dissipative part, stored + dissipated then equals the trapezoidal work ``½(T0+T1)(x1-x0)``
exactly, step by step; for the nonlinear springs it holds to O(h^3) per step.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from droptower.rheology.numba_cache import (cache_available, compile_once_across_processes, prefer_fork_safe_threads,
                                            row_loop_options)

# kernel codes
LINEAR_SPRING = 0
TABLE_SPRING = 1
CUBIC_SPRING = 2
DASHPOT = 3
MAXWELL = 4
SLIDER_BANK = 5
VARIABLE_MAXWELL = 6
PFEFFER = 7
PAYNE = 8
FILLER_NETWORK = 9
MAXWELL_BANK = 10
LARGE_STRAIN_NETWORK = 11

# named slots of the parameter and state slices (the layouts of droptower.rheology.kinds)
# ---------------------------------------------------------------- slot offsets (generated)
# from droptower.rheology.kinds by `python -m droptower.rheology.slots`: do not edit by hand
S_STORED_ENERGY_J = 0
S_DISSIPATED_ENERGY_J = 1
S_TORQUE_NM = 2
N_HEADER = 3
P_LINEAR_SPRING_K = 0
P_TABLE_SPRING_N = 0
P_TABLE_SPRING_TABLES = 1
P_CUBIC_SPRING_A = 0
P_CUBIC_SPRING_B = 1
P_DASHPOT_C = 0
P_MAXWELL_K = 0
P_MAXWELL_C = 1
S_MAXWELL_ELONGATION_RAD = 3
S_MAXWELL_CACHED_HK = 4
S_MAXWELL_CACHED_C = 5
S_MAXWELL_CACHED_DECAY = 6
S_MAXWELL_CACHED_GAIN = 7
P_SLIDER_BANK_N = 0
P_SLIDER_BANK_V_R = 1
P_SLIDER_BANK_P = 2
P_SLIDER_BANK_CONSTRICTION_P = 3
P_SLIDER_BANK_CONSTRICTION_K = 4
P_SLIDER_BANK_TABLES = 5
S_SLIDER_BANK_BLOCKS = 3
P_VARIABLE_MAXWELL_K0 = 0
P_VARIABLE_MAXWELL_GAIN = 1
P_VARIABLE_MAXWELL_C0 = 2
P_VARIABLE_MAXWELL_NK = 3
P_VARIABLE_MAXWELL_NC = 4
P_VARIABLE_MAXWELL_FORCE_MODE = 5
P_VARIABLE_MAXWELL_TABLES = 6
S_VARIABLE_MAXWELL_ELONGATION_RAD = 3
S_VARIABLE_MAXWELL_CACHED_H = 4
S_VARIABLE_MAXWELL_CACHED_C_OVER_H = 5
P_PFEFFER_K1 = 0
P_PFEFFER_ALPHA = 1
P_PFEFFER_BETA = 2
P_PFEFFER_GAMMA = 3
S_PFEFFER_Z_RAD = 3
S_PFEFFER_CACHED_LAMBDA_H = 4
S_PFEFFER_CACHED_DECAY = 5
P_PAYNE_STIFFNESS = 0
P_PAYNE_CRITICAL_ANGLE = 1
P_PAYNE_EXPONENT = 2
P_PAYNE_LOSS_STIFFNESS = 3
P_PAYNE_LOSS_PEAK_STIFFNESS = 4
P_PAYNE_CENTRE_RELAXATION_TIME = 5
P_PAYNE_MEMORY_TIME = 6
P_PAYNE_STORAGE_FREQUENCY_EXPONENT = 7
P_PAYNE_LOSS_FREQUENCY_EXPONENT = 8
P_PAYNE_REFERENCE_OMEGA = 9
P_PAYNE_REST_RELAXATION_TIME = 10
S_PAYNE_ELONGATION_RAD = 3
S_PAYNE_STIFFNESS = 4
S_PAYNE_DAMPING = 5
S_PAYNE_OMEGA = 6
S_PAYNE_PEAK_ELONGATION = 7
S_PAYNE_PEAK_RATE = 8
S_PAYNE_ELAPSED_S = 9
S_PAYNE_HALF_CYCLE_SIGN = 10
S_PAYNE_MODE = 11
S_PAYNE_CACHED_CENTRE_DECAY = 12
S_PAYNE_CACHED_H = 13
S_PAYNE_CACHED_REST_DECAY = 14
P_FILLER_NETWORK_N = 0
P_FILLER_NETWORK_BREAKDOWN_ANGLE = 1
P_FILLER_NETWORK_TWO_M = 2
P_FILLER_NETWORK_RECOVERY_TIME = 3
P_FILLER_NETWORK_CENTRE_RELAXATION_TIME = 4
P_FILLER_NETWORK_REST_RATE = 5
P_FILLER_NETWORK_TABLES = 6
S_FILLER_NETWORK_DAMAGE = 3
S_FILLER_NETWORK_CENTRE_ELONGATION_RAD = 4
S_FILLER_NETWORK_CACHED_H = 5
S_FILLER_NETWORK_CACHED_H_OVER_CENTRE_TIME = 6
S_FILLER_NETWORK_CACHED_CENTRE_OVER_RECOVERY_TIME = 7
S_FILLER_NETWORK_CACHED_INVERSE_REST_STEP = 8
S_FILLER_NETWORK_CACHED_G_CAP = 9
S_FILLER_NETWORK_CACHED_THRESHOLD_RAD = 10
S_FILLER_NETWORK_BLOCKS = 11
P_MAXWELL_BANK_N = 0
P_MAXWELL_BANK_TABLES = 1
S_MAXWELL_BANK_CACHED_H = 3
S_MAXWELL_BANK_CACHED_K1 = 4
S_MAXWELL_BANK_CACHED_C1 = 5
S_MAXWELL_BANK_BLOCKS = 6
P_LARGE_STRAIN_NETWORK_N = 0
P_LARGE_STRAIN_NETWORK_STIFFNESS = 1
P_LARGE_STRAIN_NETWORK_GAIN = 2
P_LARGE_STRAIN_NETWORK_EXPONENT = 3
P_LARGE_STRAIN_NETWORK_NETWORK_STIFFNESS = 4
P_LARGE_STRAIN_NETWORK_FRICTION_GAIN = 5
P_LARGE_STRAIN_NETWORK_DAMAGE_MAX = 6
P_LARGE_STRAIN_NETWORK_DAMAGE_ANGLE = 7
P_LARGE_STRAIN_NETWORK_DAMAGE_EXPONENT = 8
P_LARGE_STRAIN_NETWORK_DAMAGE_TRAVEL = 9
P_LARGE_STRAIN_NETWORK_TRAVEL_SOFTENING = 10
P_LARGE_STRAIN_NETWORK_TRAVEL_EXPONENT = 11
P_LARGE_STRAIN_NETWORK_SLIP_HARDENING = 12
P_LARGE_STRAIN_NETWORK_DAMAGE_SIDES = 13
P_LARGE_STRAIN_NETWORK_TABLES = 14
S_LARGE_STRAIN_NETWORK_DAMAGE = 3
S_LARGE_STRAIN_NETWORK_PEAK_ANGLE_RAD = 4
S_LARGE_STRAIN_NETWORK_TRAVEL_RAD = 5
S_LARGE_STRAIN_NETWORK_REVERSAL_ANGLE_RAD = 6
S_LARGE_STRAIN_NETWORK_DIRECTION = 7
S_LARGE_STRAIN_NETWORK_DAMAGE_NEGATIVE = 8
S_LARGE_STRAIN_NETWORK_PEAK_NEGATIVE_ANGLE_RAD = 9
S_LARGE_STRAIN_NETWORK_BLOCKS = 10
# ---------------------------------------------------------------- end of the generated slot offsets

CACHE = cache_available()  # False where no cache folder is writable: compiled at every start instead
prefer_fork_safe_threads()
JIT = dict(cache=CACHE, nogil=True, fastmath=False, error_model="numpy")


# ---------------------------------------------------------------- helpers
@njit(**JIT)
def _segment(x, xs, n):
    """Index i of the table segment [xs[i], xs[i+1]] used at x (the end segments extend outwards)."""
    if x <= xs[0]:
        return 0
    if x >= xs[n - 1]:
        return n - 2
    lo = 0
    hi = n - 1
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if xs[mid] <= x:
            lo = mid
        else:
            hi = mid
    return lo


@njit(**JIT)
def _interp(x, xs, ys, n):
    """Piecewise-linear interpolation with linear extrapolation by the end segments."""
    i = _segment(x, xs, n)
    t = (x - xs[i]) / (xs[i + 1] - xs[i])
    return ys[i] + t * (ys[i + 1] - ys[i])


@njit(**JIT)
def _ipow(u, p):
    """u**p for a non-negative integer p, by multiplications."""
    r = 1.0
    b = u
    while p > 0:
        if p & 1:
            r *= b
        b *= b
        p >>= 1
    return r


# ---------------------------------------------------------------- elastic elements
@njit(inline="always", **JIT)
def linear_spring(p, po, s, so, x0, x1, h):
    """T = k x.  params: [k]."""
    k = p[po + P_LINEAR_SPRING_K]
    s[so + S_STORED_ENERGY_J] = 0.5 * k * x1 * x1
    s[so + S_TORQUE_NM] = k * x1
    return s[so + S_TORQUE_NM]


@njit(**JIT)
def table_spring(p, po, s, so, x0, x1, h):
    """T = f(x), piecewise linear through the table (Scheiblegger et al.'s (2013) k1 table).

    params: [n, x_1..x_n, T_1..T_n, E_1..E_n] with E_i the stored energy at x_i (the integral
    of f from 0, precomputed), so the energy at x is E_i plus one trapezoid.
    """
    n = int(p[po + P_TABLE_SPRING_N])
    xs = p[po + P_TABLE_SPRING_TABLES:po + P_TABLE_SPRING_TABLES + n]
    ys = p[po + P_TABLE_SPRING_TABLES + n:po + P_TABLE_SPRING_TABLES + 2 * n]
    i = _segment(x1, xs, n)
    torque = ys[i] + (x1 - xs[i]) / (xs[i + 1] - xs[i]) * (ys[i + 1] - ys[i])
    s[so + S_STORED_ENERGY_J] = p[po + P_TABLE_SPRING_TABLES + 2 * n + i] + 0.5 * (ys[i] + torque) * (x1 - xs[i])
    s[so + S_TORQUE_NM] = torque
    return torque


@njit(inline="always", **JIT)
def cubic_spring(p, po, s, so, x0, x1, h):
    """T = A x^3 + B x (Heine & Plagemann 2014). params: [A, B]."""
    a = p[po + P_CUBIC_SPRING_A]
    b = p[po + P_CUBIC_SPRING_B]
    s[so + S_STORED_ENERGY_J] = 0.25 * a * x1 ** 4 + 0.5 * b * x1 * x1
    s[so + S_TORQUE_NM] = a * x1 ** 3 + b * x1
    return s[so + S_TORQUE_NM]


# ---------------------------------------------------------------- dissipative elements
@njit(inline="always", **JIT)
def dashpot(p, po, s, so, x0, x1, h):
    """T = c dx/dt, the rate of the step. params: [c]."""
    t1 = p[po + P_DASHPOT_C] * (x1 - x0) / h
    s[so + S_DISSIPATED_ENERGY_J] += 0.5 * (s[so + S_TORQUE_NM] + t1) * (x1 - x0)
    s[so + S_TORQUE_NM] = t1
    return t1


@njit(inline="always", **JIT)
def maxwell(p, po, s, so, x0, x1, h):
    """Spring k in series with dashpot c (the zero-dimensional model paper, eq. 1), exact for a linear ramp in the step.

    params: [k, c]; internal: spring elongation e (de/dt = dx/dt - (k/c) e), then a cache of
    the step's coefficients, keyed on h k and c: e1 = e0 exp(-h k/c) + dx tau (1 - exp(-h k/c)) / h.
    """
    k = p[po + P_MAXWELL_K]
    c = p[po + P_MAXWELL_C]
    e0 = s[so + S_MAXWELL_ELONGATION_RAD]
    # exp() and divisions only when h or the parameters change
    if s[so + S_MAXWELL_CACHED_HK] != h * k or s[so + S_MAXWELL_CACHED_C] != c:
        tau = c / k
        s[so + S_MAXWELL_CACHED_HK] = h * k
        s[so + S_MAXWELL_CACHED_C] = c
        s[so + S_MAXWELL_CACHED_DECAY] = np.exp(-h / tau)
        s[so + S_MAXWELL_CACHED_GAIN] = tau * (1.0 - s[so + S_MAXWELL_CACHED_DECAY]) / h
    e1 = e0 * s[so + S_MAXWELL_CACHED_DECAY] + (x1 - x0) * s[so + S_MAXWELL_CACHED_GAIN]
    t1 = k * e1
    # dashpot stroke = (x1 - x0) - (e1 - e0), carrying the mean spring force
    s[so + S_DISSIPATED_ENERGY_J] += 0.5 * (s[so + S_TORQUE_NM] + t1) * ((x1 - x0) - (e1 - e0))
    s[so + S_STORED_ENERGY_J] = 0.5 * k * e1 * e1
    s[so + S_TORQUE_NM] = t1
    s[so + S_MAXWELL_ELONGATION_RAD] = e1
    return t1


@njit(**JIT)
def _constriction(x, p_c, k_c):
    """S(x) = (|tanh(P x)| + K) / (1 + K) (Heine & Plagemann's (2014) constriction of the loop waist)."""
    return (abs(np.tanh(p_c * x)) + k_c) / (1.0 + k_c)


@njit(**JIT)
def _ipow_small(u, p):
    """u**p for an integer 0 <= p < 32 without branches (so that loops over it vectorise)."""
    r = 1.0
    b = u
    for bit in range(5):
        r *= b if (p >> bit) & 1 else 1.0
        b *= b
    return r


@njit(**JIT)
def _slide_newton(u, bb, a, p_exp, tol):
    """Finish the implicit step u + A u^p = |B| of one elastoslide element by Newton's method.

    The left side is increasing and convex for u > 0, so Newton's method converges
    monotonically from any start at or above the root; ``u`` (the fast pass's last iterate,
    which lies above the root after its first step) is clipped to the upper bounds |B| and
    (|B|/A)^(1/p).
    """
    u = min(u, bb) if u >= 0.0 else bb  # a NaN (an overflow in the fast pass) restarts from |B|
    for it in range(200):
        up = _ipow(u, p_exp - 1)
        if it == 20 or not np.isfinite(a * up * u):  # slow, or overflowing: the tighter bound
            u = min(u, (bb / a) ** (1.0 / p_exp))
            up = _ipow(u, p_exp - 1)
        step = (u + a * up * u - bb) / (1.0 + p_exp * a * up)
        u -= step
        if abs(step) <= tol * u:
            break
    return u


NEWTON_FAST_ITERATIONS = 3
NEWTON_TOL = 1e-11
FAST_STEP_TOL = 3e-7
FAST_MAX_EXPONENT = 32  # _ipow_small handles exponents below 32 (5 bits)


@njit(**JIT)
def _bank_rate_dependent(scales, yield_angles, elong, trial, work, v_r, p_exp, n, dx, h):
    """Backward-Euler update of every element of a rate-dependent elastoslide bank.

    the elastoslide paper, eq. 13/17: de/dt = dx/dt - v_r (k e / f*)^p. In the normalised elongation
    u = k e / f* (``scales`` = k / f*) the implicit step reads u + A u^p = B with
    A = h v_r k / f* and B = k (e0 + dx) / f*, an odd, increasing function of u, convex for
    u > 0: one root, found by Newton's method (``yield_angles`` = f* / k = 1 / scales, to
    multiply rather than divide). A branch-free pass of a fixed number of iterations,
    warm-started from the previous elongation (steady motion changes it little), runs over all
    elements and vectorises; the few elements it leaves unconverged (at stick-slip
    transitions; marked NaN, their last iterate kept in ``work``) are finished one by one.
    """
    if p_exp >= FAST_MAX_EXPONENT:  # beyond the branch-free power: element by element
        for i in range(n):
            b = scales[i] * (elong[i] + dx)
            u = _slide_newton(abs(b), abs(b), h * v_r * scales[i], p_exp, NEWTON_TOL)
            trial[i] = (u if b > 0.0 else -u) * yield_angles[i]
        return
    unconverged = 0
    for i in range(n):
        scale = scales[i]
        e0 = elong[i]
        b = scale * (e0 + dx)
        bb = abs(b)
        a = h * v_r * scale
        warm = scale * e0 if b > 0.0 else -scale * e0
        u = warm if (warm > 0.0) and (warm < bb) else bb
        step = 0.0
        for _ in range(NEWTON_FAST_ITERATIONS):
            up = _ipow_small(u, p_exp - 1)
            step = (u + a * up * u - bb) / (1.0 + p_exp * a * up)
            u -= step
        # Newton's error after a step is ~ (p/2) step^2 / u: a last step below FAST_STEP_TOL
        # leaves an error below ~1e-12 u (the test is False for NaN, an overflowing power)
        ok = abs(step) <= FAST_STEP_TOL * u
        unconverged += 0 if ok else 1
        work[i] = u
        trial[i] = (u if b > 0.0 else -u) * yield_angles[i] if ok else np.nan
    if unconverged:
        for i in range(n):
            if trial[i] != trial[i]:
                b = scales[i] * (elong[i] + dx)
                u = _slide_newton(work[i], abs(b), h * v_r * scales[i], p_exp, NEWTON_TOL)
                trial[i] = (u if b > 0.0 else -u) * yield_angles[i]


@njit(inline="always", **JIT)
def _bank_coulomb(yield_angles, elong, trial, n, dx):
    """Return mapping of Coulomb sliders: the elongation is clipped to f_i / k_i (``yield_angles``,
    the bank's table of those quotients: the same numbers, one division fewer per slider and step)."""
    for i in range(n):
        lim = yield_angles[i]
        trial[i] = min(max(elong[i] + dx, -lim), lim)


@njit(cache=CACHE, nogil=True, error_model="numpy", fastmath={"reassoc"})  # vectorised sums
def _bank_commit(ks, elong, trial, n, dx):
    """Commit the trial elongations; return (force, stored energy, slider work of the step)."""
    force = 0.0
    energy = 0.0
    slider_work = 0.0
    for i in range(n):
        e0 = elong[i]
        e1 = trial[i]
        elong[i] = e1
        force += ks[i] * e1
        energy += 0.5 * ks[i] * e1 * e1
        # slider stroke = dx - (e1 - e0), carrying the mean spring force
        slider_work += 0.5 * ks[i] * (e0 + e1) * (dx - (e1 - e0))
    return force, energy, slider_work


@njit(inline="always", **JIT)
def slider_bank(p, po, s, so, x0, x1, h):
    """n springs k_i each in series with a slider of limit f_i, in parallel (Iwan / Masing).

    params: [n, v_r, p, P, K, k_1..k_n, f_1..f_n, k_1/f_1..k_n/f_n, f_1/k_1..f_n/k_n]
      p == 0: Coulomb sliders (Prandtl/Jenkins elements, Heine & Plagemann 2014; return mapping);
      p odd : rate-dependent elastoslide sliders (the elastoslide paper, eq. 13), slip rate v_r (e k/f)^p;
      P > 0 : the bank's torque is scaled by the constriction S(x) (Heine & Plagemann 2014), K its floor.
    internal: elongations e_1..e_n, then 2n scratch slots (trial elongations, Newton iterates).
    """
    n = int(p[po + P_SLIDER_BANK_N])
    v_r = p[po + P_SLIDER_BANK_V_R]
    p_exp = int(p[po + P_SLIDER_BANK_P])
    p_c = p[po + P_SLIDER_BANK_CONSTRICTION_P]
    k_c = p[po + P_SLIDER_BANK_CONSTRICTION_K]
    ko = po + P_SLIDER_BANK_TABLES          # spring stiffnesses k_i
    eo = so + S_SLIDER_BANK_BLOCKS          # elongations e_i, then the scratch blocks
    dx = x1 - x0
    if p_exp == 0:
        _bank_coulomb(p[ko + 3 * n:ko + 4 * n], s[eo:eo + n], s[eo + n:eo + 2 * n], n, dx)
    else:
        # slices with offsets from 0 keep the loops free of index checks, so they vectorise
        _bank_rate_dependent(p[ko + 2 * n:ko + 3 * n], p[ko + 3 * n:ko + 4 * n],
                             s[eo:eo + n], s[eo + n:eo + 2 * n], s[eo + 2 * n:eo + 3 * n],
                             v_r, p_exp, n, dx, h)
    force, energy, slider_work = _bank_commit(p[ko:ko + n], s[eo:eo + n], s[eo + n:eo + 2 * n], n, dx)
    if p_c > 0.0:
        # the constriction modulates the bank: its dissipation is work minus stored energy
        scale = _constriction(x1, p_c, k_c)
        t1 = scale * force
        e_new = scale * energy
        s[so + S_DISSIPATED_ENERGY_J] += 0.5 * (s[so + S_TORQUE_NM] + t1) * dx - (e_new - s[so + S_STORED_ENERGY_J])
        s[so + S_STORED_ENERGY_J] = e_new
    else:
        t1 = force
        s[so + S_DISSIPATED_ENERGY_J] += slider_work
        s[so + S_STORED_ENERGY_J] = energy
    s[so + S_TORQUE_NM] = t1
    return t1


@njit(**JIT)
def _clamped(x, xs, ys, n):
    """Lookup-table value at x: linear between the knots, the end values beyond them."""
    if x <= xs[0]:
        return ys[0]
    if x >= xs[n - 1]:
        return ys[n - 1]
    return _interp(x, xs, ys, n)


@njit(**JIT)
def _vm_spring(e, p, nk):
    """Spring force of the variable Maxwell branch at its deformation e: (k0 + g|e|) e; or
    k(e) e with k from the stiffness table; or, in force mode, the force table f(e) itself."""
    if nk > 0:
        xs = p[P_VARIABLE_MAXWELL_TABLES:P_VARIABLE_MAXWELL_TABLES + nk]
        ys = p[P_VARIABLE_MAXWELL_TABLES + nk:P_VARIABLE_MAXWELL_TABLES + 2 * nk]
        if p[P_VARIABLE_MAXWELL_FORCE_MODE] > 0.0:
            return _interp(e, xs, ys, nk)
        return _clamped(e, xs, ys, nk) * e
    return (p[P_VARIABLE_MAXWELL_K0] + p[P_VARIABLE_MAXWELL_GAIN] * abs(e)) * e


@njit(**JIT)
def _vm_energy(e, p, nk):
    """Stored energy of the variable Maxwell spring: integral of its force from 0 to e."""
    if nk > 0:
        # the force is at most quadratic between knots: Simpson per segment is exact
        xs = p[P_VARIABLE_MAXWELL_TABLES:P_VARIABLE_MAXWELL_TABLES + nk]
        lo = min(0.0, e)
        hi = max(0.0, e)
        total = 0.0
        a = lo
        for j in range(nk + 1):
            b = hi
            if j < nk and xs[j] > lo and xs[j] < hi:
                b = xs[j]
            elif j < nk:
                continue
            m = 0.5 * (a + b)
            total += (b - a) / 6.0 * (_vm_spring(a, p, nk) + 4.0 * _vm_spring(m, p, nk) + _vm_spring(b, p, nk))
            a = b
        return total if e > 0.0 else -total
    return 0.5 * p[P_VARIABLE_MAXWELL_K0] * e * e + p[P_VARIABLE_MAXWELL_GAIN] * abs(e) ** 3 / 3.0


@njit(**JIT)
def _vm_dashpot(v, p, nk, nc):
    """Dashpot force c(|v|) v, with c from a table over the rate (end value beyond it) or c0."""
    if nc > 0:
        off = P_VARIABLE_MAXWELL_TABLES + 2 * nk
        return _clamped(abs(v), p[off:off + nc], p[off + nc:off + 2 * nc], nc) * v
    return p[P_VARIABLE_MAXWELL_C0] * v


@njit(**JIT)
def _vm_force_table_linear_dashpot(pv, nk, s, so, e0, dx, h):
    """The variable Maxwell step for a force table in series with a linear dashpot c, exactly.

    Backward Euler asks f(e) + (c/h) e = (c/h)(e0 + dx), whose left side is piecewise linear
    and increasing: find its segment by bisection over the knots, then solve the line. The
    stored energy comes from the knot energies precomputed after the table, the slopes of the
    segments after those. Internal: e, then the cached time step and c/h.
    """
    xs = pv[P_VARIABLE_MAXWELL_TABLES:P_VARIABLE_MAXWELL_TABLES + nk]
    ys = pv[P_VARIABLE_MAXWELL_TABLES + nk:P_VARIABLE_MAXWELL_TABLES + 2 * nk]
    if s[so + S_VARIABLE_MAXWELL_CACHED_H] != h:  # c/h only when the time step changes
        s[so + S_VARIABLE_MAXWELL_CACHED_H] = h
        s[so + S_VARIABLE_MAXWELL_CACHED_C_OVER_H] = pv[P_VARIABLE_MAXWELL_C0] / h
    beta = s[so + S_VARIABLE_MAXWELL_CACHED_C_OVER_H]
    rhs = beta * (e0 + dx)
    lo = 0
    hi = nk - 1
    if rhs <= ys[0] + beta * xs[0]:
        hi = 1
    elif rhs >= ys[nk - 1] + beta * xs[nk - 1]:
        lo = nk - 2
    else:
        while hi - lo > 1:
            mid = (lo + hi) // 2
            if ys[mid] + beta * xs[mid] <= rhs:
                lo = mid
            else:
                hi = mid
    i = lo
    slope = pv[P_VARIABLE_MAXWELL_TABLES + 3 * nk + i]  # precomputed segment slopes
    e = (rhs - ys[i] + slope * xs[i]) / (slope + beta)
    t1 = ys[i] + slope * (e - xs[i])
    s[so + S_DISSIPATED_ENERGY_J] += 0.5 * (s[so + S_TORQUE_NM] + t1) * (dx - (e - e0))
    s[so + S_STORED_ENERGY_J] = pv[P_VARIABLE_MAXWELL_TABLES + 2 * nk + i] + 0.5 * (ys[i] + t1) * (e - xs[i])
    s[so + S_TORQUE_NM] = t1
    s[so + S_VARIABLE_MAXWELL_ELONGATION_RAD] = e
    return t1


@njit(inline="always", **JIT)
def _vm_commit(pv, nk, s, so, e0, dx, e):
    """The variable Maxwell branch's state at its new elongation e: torque, stored energy and
    the dashpot's work over the stroke dx - (e - e0) (trapezoidal); returns the torque."""
    t1 = _vm_spring(e, pv, nk)
    s[so + S_DISSIPATED_ENERGY_J] += 0.5 * (s[so + S_TORQUE_NM] + t1) * (dx - (e - e0))
    s[so + S_STORED_ENERGY_J] = _vm_energy(e, pv, nk)
    s[so + S_TORQUE_NM] = t1
    s[so + S_VARIABLE_MAXWELL_ELONGATION_RAD] = e
    return t1


@njit(inline="always", **JIT)
def variable_maxwell(p, po, s, so, x0, x1, h):
    """Maxwell branch with deformation-dependent stiffness and rate-dependent damping (the zero-dimensional model paper).

    params: [k0, g, c0, nk, nc, force_mode, e_1..e_nk, k_1..k_nk (or f_1..f_nk), v_1..v_nc, c_1..c_nc]
    and, in force mode, the stored energies E_1..E_nk at the knots and the slopes of the segments.
    The spring force is f(e) = (k0 + g|e|) e (the six-parameter model's K3 linear in
    deformation), k(e) e from a stiffness lookup table, or f(e) from a force table (a static
    curve in series with the dashpot); the dashpot force is c(|v|) v. Backward Euler:
    f(e1) = d((x1 - x0 - (e1 - e0)) / h); the residual is increasing in e1 and changes sign
    between 0 and e0 + dx, so a safeguarded Newton/bisection always converges; with the
    constants k0, g and c it is a quadratic, solved in closed form.
    """
    pv = p[po:]  # the helpers index the parameters from the element's start
    nk = int(pv[P_VARIABLE_MAXWELL_NK])
    nc = int(pv[P_VARIABLE_MAXWELL_NC])
    e0 = s[so + S_VARIABLE_MAXWELL_ELONGATION_RAD]
    dx = x1 - x0
    if pv[P_VARIABLE_MAXWELL_FORCE_MODE] > 0.0 and nc == 0:
        return _vm_force_table_linear_dashpot(pv, nk, s, so, e0, dx, h)
    if nk == 0 and nc == 0:
        # the six-parameter model's branch, (k0 + g|e|) e in series with c: backward Euler's
        # (k0 + g|e|) e = (c/h)(e0 + dx - e) is a quadratic in |e| whose root has the sign of
        # r = e0 + dx; its positive root, written without cancellation (g = 0: the linear
        # Maxwell's e = (c/h) r / (k0 + c/h)), in place of the iteration below (5.5x cheaper a
        # step: benchmarks/bench_core.py)
        beta = pv[P_VARIABLE_MAXWELL_C0] / h
        r = e0 + dx
        a = pv[P_VARIABLE_MAXWELL_K0] + beta
        e = 2.0 * beta * r / (a + np.sqrt(a * a + 4.0 * pv[P_VARIABLE_MAXWELL_GAIN] * beta * abs(r)))
        return _vm_commit(pv, nk, s, so, e0, dx, e)
    lo = min(0.0, e0 + dx)
    hi = max(0.0, e0 + dx)
    e = e0 + dx if abs(e0 + dx) < abs(e0) else e0
    e = min(max(e, lo), hi)
    for _ in range(100):
        r = _vm_spring(e, pv, nk) - _vm_dashpot((dx - (e - e0)) / h, pv, nk, nc)
        if r > 0.0:
            hi = e
        elif r < 0.0:
            lo = e
        else:
            break
        de = 1e-7 * (abs(e) + 1e-9)
        r2 = _vm_spring(e + de, pv, nk) - _vm_dashpot((dx - (e + de - e0)) / h, pv, nk, nc)
        slope = (r2 - r) / de
        e_new = e - r / slope if slope > 0.0 else 0.5 * (lo + hi)
        if abs(e_new - e) <= 1e-13 * max(abs(e), 1e-12):  # converged (maybe onto the bracket's edge)
            e = e_new
            break
        if not (lo < e_new < hi):
            e_new = 0.5 * (lo + hi)
        e = e_new
    return _vm_commit(pv, nk, s, so, e0, dx, e)


@njit(**JIT)
def pfeffer(p, po, s, so, x0, x1, h):
    """Pfeffer frequency part (Scheiblegger et al. 2013, docs/theory.md#pfeffer): k1 parallel to c1 in series with (k2 || c2).

    params: [k1, alpha, beta, gamma] with k2 = alpha k1, c1 = gamma k1, c2 = beta c1.
    internal: z, the Kelvin-Voigt deflection, then a cache of (lambda h, exp(-lambda h)); dz/dt = (du/dt - (alpha/gamma) z) / (1 + beta),
    integrated exactly for the step's constant du/dt. F = k1 [u + gamma (du/dt - dz/dt)].
    """
    k1 = p[po + P_PFEFFER_K1]
    alpha = p[po + P_PFEFFER_ALPHA]
    beta = p[po + P_PFEFFER_BETA]
    gamma = p[po + P_PFEFFER_GAMMA]
    z0 = s[so + S_PFEFFER_Z_RAD]
    v = (x1 - x0) / h
    lam = alpha / (gamma * (1.0 + beta))
    if s[so + S_PFEFFER_CACHED_LAMBDA_H] != lam * h:  # exp() only when the time step (or the parameters) change
        s[so + S_PFEFFER_CACHED_LAMBDA_H] = lam * h
        s[so + S_PFEFFER_CACHED_DECAY] = np.exp(-lam * h)
    decay = s[so + S_PFEFFER_CACHED_DECAY]
    z1 = z0 * decay + v / (1.0 + beta) * (1.0 - decay) / lam
    zdot1 = (v - alpha / gamma * z1) / (1.0 + beta)
    c1 = gamma * k1
    k2 = alpha * k1
    branch1 = c1 * (v - zdot1)
    t1 = k1 * x1 + branch1
    branch0 = s[so + S_TORQUE_NM] - k1 * x0
    mean_branch = 0.5 * (branch0 + branch1)
    # c1 stroke (dx - dz) and c2 stroke dz, c2 force = branch force - k2 z
    s[so + S_DISSIPATED_ENERGY_J] += (mean_branch * ((x1 - x0) - (z1 - z0))
                                      + (mean_branch - 0.5 * k2 * (z0 + z1)) * (z1 - z0))
    s[so + S_STORED_ENERGY_J] = 0.5 * k1 * x1 * x1 + 0.5 * k2 * z1 * z1
    s[so + S_TORQUE_NM] = t1
    s[so + S_PFEFFER_Z_RAD] = z1
    return t1



# ---------------------------------------------------------------- amplitude envelope (Payne effect)
MIN_OMEGA = 2.0 * np.pi * 0.01  # rad/s: below 0.01 Hz a half cycle is not an oscillation
REST_EXIT = 100.0  # a rest ends when the rate exceeds the largest rate seen while resting this much
MIN_HALF_CYCLE_STEPS = 8  # a half cycle of fewer steps cannot tell a frequency (nor is one resolved)


@njit(**JIT)
def _kraus(amp, angle_c, m):
    """(1 / (1 + u^2), 2 u / (1 + u^2)) with u = (amp / angle_c)^m: Kraus's (1984) storage and
    loss-peak shapes (1 and 0 at zero amplitude, 1/2 and 1 at angle_c)."""
    u = (amp / angle_c) ** m
    inv = 1.0 / (1.0 + u * u)
    return inv, 2.0 * u * inv


@njit(**JIT)
def payne(p, po, s, so, x0, x1, h):
    """Kraus-type amplitude-dependent complex stiffness, causal and passive (docs/theory.md#payne).

    A spring k(A) acting on the elongation e = x - x_c about a centre x_c that follows the
    mean angle (a Maxwell relaxation of time ``centre_tau``, so a held preload relaxes it),
    in parallel with a dashpot c = K''(A) / w. A is the amplitude of the half cycle under
    way and w the oscillation's angular frequency, both read from the motion itself:

    - a half cycle runs from one zero crossing of e to the next; w is the ratio of the
      velocity and elongation peaks of the last completed one (amplitude-independent, so it
      does not lag a decaying oscillation); before one is known (from rest, or after
      ``memory_s`` without a crossing) the running peaks of the current one are used;
    - A = max(running |e| peak, running |de/dt| peak / w): for a harmonic motion the
      velocity peak at the crossing already gives the half cycle's amplitude.

    In a harmonic motion of amplitude A about the centre the loop is an exact ellipse:
    K' = dK / (1 + u^2), K'' = loss_0 + 2 loss_peak u / (1 + u^2), u = (A/A_c)^m (Kraus 1984)
    at every frequency: rate-independent, as filled rubber's Payne effect is to first order.
    Passivity (exact for the trapezoidal work the core books): the spring's stiffness falls
    only in steps where e keeps its sign and rises only in the step where e changes sign; the
    trapezoidal work then exceeds the change of stored energy by e0 e1 (k_old - k_new) / 2 >= 0
    in both cases (the filler network breaks down under load and re-forms unstrained). The
    dashpot's coefficient falls only in steps where the rate keeps its sign, which keeps the
    trapezoidal work of c v non-negative over any history.

    A weak frequency dependence (filled rubber's K' and K'' rise slowly with frequency) scales
    K' by (w/w_ref)^beta_s and K'' by (w/w_ref)^beta_l, w again the oscillation's own frequency
    (no relaxation time is involved, so a free decay stays one damped mode).

    At rest (no zero crossing for ``memory_s``) the centre follows the angle with the short
    ``rest_tau`` (a held preload leaves no offset) and the network re-forms completely,
    unstrained at the current angle (the centre moves so that the torque stays; the stored energy
    falls): a drop test after a rest starts from the virgin element, whatever the preload.

    params: [dK, angle_c, m, loss_0, loss_peak, centre_tau, memory_s, beta_s, beta_l, w_ref, rest_tau]
    internal: e, k, c, w, peak_e, peak_v, time since the crossing, sign of the half cycle,
    mode (0 virgin, 1 oscillating, 2 at rest: no crossing for memory_s, until the rate exceeds
    100x the largest rate seen resting), cached exp(-h/centre_tau), h and exp(-h/rest_tau).
    """
    dk = p[po + P_PAYNE_STIFFNESS]
    angle_c = p[po + P_PAYNE_CRITICAL_ANGLE]
    m = p[po + P_PAYNE_EXPONENT]
    loss0 = p[po + P_PAYNE_LOSS_STIFFNESS]
    loss_peak = p[po + P_PAYNE_LOSS_PEAK_STIFFNESS]
    tau = p[po + P_PAYNE_CENTRE_RELAXATION_TIME]
    memory = p[po + P_PAYNE_MEMORY_TIME]
    beta_s = p[po + P_PAYNE_STORAGE_FREQUENCY_EXPONENT]
    beta_l = p[po + P_PAYNE_LOSS_FREQUENCY_EXPONENT]
    omega_ref = p[po + P_PAYNE_REFERENCE_OMEGA]
    rest_tau = p[po + P_PAYNE_REST_RELAXATION_TIME]
    if s[so + S_PAYNE_CACHED_H] != h:
        s[so + S_PAYNE_CACHED_H] = h
        s[so + S_PAYNE_CACHED_CENTRE_DECAY] = np.exp(-h / tau)
        s[so + S_PAYNE_CACHED_REST_DECAY] = np.exp(-h / rest_tau)
    resting = s[so + S_PAYNE_MODE] == 2.0
    if resting:  # at rest the centre follows the angle fast: a held preload leaves no offset
        tau = rest_tau
        decay = s[so + S_PAYNE_CACHED_REST_DECAY]
    else:
        decay = s[so + S_PAYNE_CACHED_CENTRE_DECAY]
    e0 = s[so + S_PAYNE_ELONGATION_RAD]
    k_old = s[so + S_PAYNE_STIFFNESS]
    dx = x1 - x0
    # centre relaxation: de/dt = dx/dt - e / tau, exact for the step's constant rate
    e1 = e0 * decay + dx * tau * (1.0 - decay) / h
    rate_e = (e1 - e0) / h
    w = s[so + S_PAYNE_OMEGA]
    peak_e = s[so + S_PAYNE_PEAK_ELONGATION]
    peak_v = s[so + S_PAYNE_PEAK_RATE]
    elapsed = s[so + S_PAYNE_ELAPSED_S] + h
    sign = s[so + S_PAYNE_HALF_CYCLE_SIGN]
    crossed = (e1 > 0.0 and sign < 0.0) or (e1 < 0.0 and sign > 0.0) or (sign == 0.0 and e1 != 0.0)
    if crossed:
        # a completed half cycle gives the frequency by its duration (the zero crossings of a
        # damped sinusoid are exactly pi/w_d apart) if it was an oscillation: not longer than
        # memory_s nor shorter than a few steps (a rig's jitter about a relaxed centre crosses
        # zero from step to step), and its peaks' ratio (w e^(delta T/4) for a damped sinusoid)
        # agrees within a factor 2 (a rest between a stray crossing and an impact is no half
        # cycle). The crossing's time inside the step (e linear in between) gives the half
        # period to O(h^2).
        theta = e0 / (e0 - e1) if e0 * e1 < 0.0 else 1.0
        duration = elapsed - (1.0 - theta) * h
        w = 0.0
        if sign != 0.0 and MIN_HALF_CYCLE_STEPS * h <= duration <= memory and peak_e > 0.0:
            w_time = np.pi / duration
            if 0.5 * w_time <= peak_v / peak_e <= 2.0 * w_time:
                w = max(w_time, MIN_OMEGA)
        peak_e = 0.0
        peak_v = 0.0
        elapsed = (1.0 - theta) * h  # from the crossing to the end of this step
        sign = 1.0 if e1 > 0.0 else -1.0
    mode = s[so + S_PAYNE_MODE]  # 0: virgin, 1: oscillating, 2: at rest
    rest = False
    started = False
    if crossed:
        started = mode == 2.0  # a crossing out of a rest starts the motion too
        mode = 1.0
    elif mode == 2.0:
        if abs(rate_e) > REST_EXIT * peak_v:
            # motion starts from rest (an impact, a test's ramp): a half cycle begins here. This
            # step's rate is not the motion's (an impact is a jump in rate; a rig may even move
            # the struck body within the step), so the velocity peak is read from the next step
            mode, peak_e, peak_v, elapsed, started = 1.0, 0.0, 0.0, 0.0, True
        else:
            rest = True
    elif elapsed > memory:
        # no crossing for memory_s: a rest. It is no oscillation, so it carries no hysteretic
        # loss and forgets the frequency; the largest rate seen while resting (creep of the
        # centre, a rig's jitter) is what the start of a motion must exceed
        mode, rest, w, peak_e, peak_v = 2.0, True, 0.0, 0.0, 0.0
    peak_e = max(peak_e, abs(e1))
    if not started:
        peak_v = max(peak_v, abs(rate_e))
    amp = peak_e
    omega = w
    if w > 0.0:
        amp = max(amp, peak_v / w)
    elif peak_e > 0.0:
        # no completed half cycle yet (from rest): the running peaks (virgin loading; their
        # ratio is the frequency at the reversal, above it before: a little less damping in
        # this first half cycle. The motion itself cannot tell the frequency earlier: a free
        # decay's rate first falls by its damping, only later by its stiffness)
        omega = peak_v / peak_e
    storage, peak_shape = _kraus(amp, angle_c, m)
    # weak frequency dependence at the oscillation's own frequency (a completed half cycle's;
    # the reference frequency before one is known): K' ~ w^beta_s, K'' ~ w^beta_l
    ratio = w / omega_ref if w > 0.0 else 1.0
    k_new = dk * storage * ratio ** beta_s
    if rest:
        # at rest the network re-forms completely, unstrained at the current angle: the centre
        # moves so that the torque stays the same (k e is kept, the stored energy k e^2 / 2
        # falls): passive anywhere, not only at a zero crossing. A rest has zero amplitude.
        k_new = dk
        if k_new > k_old and k_old > 0.0:
            e1 = e1 * k_old / k_new
        else:
            k_new = min(k_new, k_old) if s[so + S_PAYNE_MODE] > 0.0 else k_new
    elif crossed and e0 * e1 < 0.0:
        k_new = max(k_new, k_old)  # a fall waits for the next step (keeps the step passive)
    elif s[so + S_PAYNE_MODE] > 0.0:
        k_new = min(k_new, k_old)  # within a half cycle the network only breaks down
    c = 0.0
    if omega > 0.0 and not rest:
        c = (loss0 + loss_peak * peak_shape) * ratio ** beta_l / max(omega, MIN_OMEGA)
    # the dashpot's coefficient may fall only while the rate keeps its sign: then the
    # trapezoidal work of its force c v is >= 0 over any history (each step's c v^2 h / 2
    # covers the cross terms of the reversals next to it)
    c_old = s[so + S_PAYNE_DAMPING]
    if c < c_old and (s[so + S_TORQUE_NM] - k_old * e0) * dx < 0.0:
        c = c_old
    t1 = k_new * e1 + c * dx / h
    stored1 = 0.5 * k_new * e1 * e1
    # dissipated = trapezoidal work of the step - change of stored energy (dashpot, centre
    # relaxation, breakdown and re-forming of the network all included)
    s[so + S_DISSIPATED_ENERGY_J] += 0.5 * (s[so + S_TORQUE_NM] + t1) * dx - (stored1 - s[so + S_STORED_ENERGY_J])
    s[so + S_STORED_ENERGY_J] = stored1
    s[so + S_TORQUE_NM] = t1
    s[so + S_PAYNE_ELONGATION_RAD] = e1
    s[so + S_PAYNE_STIFFNESS] = k_new
    s[so + S_PAYNE_DAMPING] = c
    s[so + S_PAYNE_OMEGA] = w
    s[so + S_PAYNE_PEAK_ELONGATION] = peak_e
    s[so + S_PAYNE_PEAK_RATE] = peak_v
    s[so + S_PAYNE_ELAPSED_S] = elapsed
    s[so + S_PAYNE_HALF_CYCLE_SIGN] = sign
    s[so + S_PAYNE_MODE] = max(mode, 1.0)
    return t1


@njit(cache=CACHE, nogil=True, error_model="numpy", fastmath={"reassoc"})  # vectorised sums
def _maxwell_terms(p, ko, s, eo, n, dx):
    """Advance the elongations s[eo:eo+n] of n Maxwell terms (springs p[ko:ko+n]) by the step's
    cached decay and ramp factors (after them in s); return (torque, stored, dissipated)."""
    torque = 0.0
    energy = 0.0
    dissipated = 0.0
    for i in range(n):
        k = p[ko + i]
        e0 = s[eo + i]
        e1 = e0 * s[eo + n + i] + dx * s[eo + 2 * n + i]
        s[eo + i] = e1
        torque += k * e1
        energy += k * e1 * e1
        # dashpot stroke dx - (e1 - e0), carrying the mean spring force
        dissipated += k * (e0 + e1) * (dx - (e1 - e0))
    return torque, 0.5 * energy, 0.5 * dissipated


@njit(inline="always", **JIT)
def maxwell_bank(p, po, s, so, x0, x1, h):
    """n Maxwell terms in parallel in one pass (a Prony series: the power-law branch), each
    exact as :func:`maxwell` for the step's constant rate.

    params: [n, k_1..k_n, c_1..c_n]; internal: cached h, k_1, c_1 (the key of the cache), then
    the elongations e_1..e_n, the decays exp(-h k_i/c_i) and the ramp factors tau_i (1 - decay_i)/h.
    """
    n = int(p[po + P_MAXWELL_BANK_N])
    eo = so + S_MAXWELL_BANK_BLOCKS
    ko = po + P_MAXWELL_BANK_TABLES  # k_1..k_n, then c_1..c_n
    if (s[so + S_MAXWELL_BANK_CACHED_H] != h or s[so + S_MAXWELL_BANK_CACHED_K1] != p[ko]
            or s[so + S_MAXWELL_BANK_CACHED_C1] != p[ko + n]):
        s[so + S_MAXWELL_BANK_CACHED_H] = h
        s[so + S_MAXWELL_BANK_CACHED_K1] = p[ko]
        s[so + S_MAXWELL_BANK_CACHED_C1] = p[ko + n]
        for i in range(n):
            tau = p[ko + n + i] / p[ko + i]
            s[eo + n + i] = np.exp(-h / tau)
            s[eo + 2 * n + i] = -tau * np.expm1(-h / tau) / h
    torque, energy, dissipated = _maxwell_terms(p, ko, s, eo, n, x1 - x0)
    s[so + S_STORED_ENERGY_J] = energy
    s[so + S_DISSIPATED_ENERGY_J] += dissipated
    s[so + S_TORQUE_NM] = torque
    return torque


# ---------------------------------------------------------------- filler network (Payne effect, any history)
#: the breakdown threshold is cached for an intact fraction this share of the damage above the
#: current one (a power per renewal instead of one per step; the result is the same)
FN_THRESHOLD_CAP = 0.01
FN_THIRD = 1.0 / 3.0


@njit(cache=CACHE, nogil=True, error_model="numpy", fastmath={"reassoc"})  # vectorised sums
def _filler_sliders(ks, yield_angles, elong, n, ratio, dx):
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
    """One step of the filler network from x0 to x1 (rad) over h (s); returns its torque (N*m).
    Per-step update of the ``filler_network`` element: the Payne effect of filled rubber from
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
    - **Re-formation only while held**: the centre's and the stress's relaxation and the recovery
      run at the rates above times rest = 1 / (1 + |dx/dt| / ``rest_rate``) (filler contacts
      re-form and age at rest and are renewed by sliding, as in the ageing law of rate-and-state
      friction, Dieterich 1979): a held twist relaxes and recovers, a slow sine does not relax
      the network (no loss peak at 1 / (2 pi centre_relaxation_time); docs/theory.md#filler-network).

    Energy (exact to round-off for the trapezoidal work ½ (T0 + T1) dx the core books): the
    Iwan springs store g Σ ½ k_i e_i², the sliders dissipate their mean force times their slip.
    Breakdown lowers g at fixed elongations (stored energy is released, dissipated: fracture of
    filler-filler bonds); it is booked at the end of a step only where that step's balance stays
    non-negative, else one step later. Recovery re-forms bonds unstrained: the elongations are
    scaled by g_old / g_new so the torque is kept while the stored energy falls. So the element is
    passive for any history and step, with no stability limit (the slider update is a return
    mapping, the centre's relaxation and the recovery exact for the step's constant rate).

    params: [n, breakdown_angle, 2 m, recovery_time, centre_relaxation_time, rest_rate, k_1..k_n,
    a_1..a_n] (the intact network's spring stiffnesses and the yield angles).
    internal (after the common header): [damage 1 - g, e_c, cached h, h / centre_relaxation_time,
    centre_relaxation_time / recovery_time, 1 / (h rest_rate), a cap of g and the elongation below which nothing
    breaks while g <= cap, e_1..e_n].

    The sliders' return mapping is that of a Coulomb slider bank (:func:`kernels.slider_bank`),
    fused here with the recovery's rescaling and the sums in one vectorised pass.
    """
    n = int(p[po + P_FILLER_NETWORK_N])
    breakdown_angle = p[po + P_FILLER_NETWORK_BREAKDOWN_ANGLE]
    two_m = p[po + P_FILLER_NETWORK_TWO_M]
    if s[so + S_FILLER_NETWORK_CACHED_H] != h:  # the step's share of the relaxation and recovery times, when it changes
        s[so + S_FILLER_NETWORK_CACHED_H] = h
        s[so + S_FILLER_NETWORK_CACHED_H_OVER_CENTRE_TIME] = h / p[po + P_FILLER_NETWORK_CENTRE_RELAXATION_TIME]
        s[so + S_FILLER_NETWORK_CACHED_CENTRE_OVER_RECOVERY_TIME] = (p[po + P_FILLER_NETWORK_CENTRE_RELAXATION_TIME]
                                                                     / p[po + P_FILLER_NETWORK_RECOVERY_TIME])
        s[so + S_FILLER_NETWORK_CACHED_INVERSE_REST_STEP] = 1.0 / (h * p[po + P_FILLER_NETWORK_REST_RATE])
    dx = x1 - x0
    # the network re-forms only while it is held (docs/theory.md#filler-network): at the step's
    # rate |dx|/h its centre, its stress and its structure relax with the rates
    # 1/centre_relaxation_time and 1/recovery_time times rest = 1 / (1 + |dx|/h / rest_rate);
    # exact for the step's constant rate
    # h rest / centre_relaxation_time
    rate = (s[so + S_FILLER_NETWORK_CACHED_H_OVER_CENTRE_TIME]
            / (1.0 + abs(dx) * s[so + S_FILLER_NETWORK_CACHED_INVERSE_REST_STEP]))
    if rate < 1e-8:  # a moving network: the series to rate (error rate^2 / 2: round-off)
        gain = 1.0 - 0.5 * rate
        centre_decay = 1.0 - rate
    elif rate < 1e-3:  # the Taylor series to rate^4 (error < 1e-17 + round-off)
        gain = 1.0 - 0.5 * rate * (1.0 - rate * FN_THIRD * (1.0 - 0.25 * rate))
        centre_decay = 1.0 - rate * gain
    else:
        centre_decay = np.exp(-rate)
        gain = (1.0 - centre_decay) / rate
    damage0 = s[so + S_FILLER_NETWORK_DAMAGE]
    g0 = 1.0 - damage0
    centre_elongation = s[so + S_FILLER_NETWORK_CENTRE_ELONGATION_RAD] * centre_decay + dx * gain
    # recovery towards the intact network, then breakdown by the elongation about the centre:
    # g = min(g_rec, g_eq(|e_c|)). g_eq(|e_c|) >= g_rec below the elongation where g_eq equals
    # g_rec; that elongation falls as g_rec rises, so the one of a cap above g_rec bounds it
    recovery = rate * s[so + S_FILLER_NETWORK_CACHED_CENTRE_OVER_RECOVERY_TIME]  # h rest / recovery_time
    g_rec = 1.0 - damage0 * ((1.0 - recovery * (1.0 - 0.5 * recovery)) if recovery < 1e-5 else np.exp(-recovery))
    if g_rec > s[so + S_FILLER_NETWORK_CACHED_G_CAP]:
        cap = g_rec + FN_THRESHOLD_CAP * damage0
        s[so + S_FILLER_NETWORK_CACHED_G_CAP] = cap
        threshold = breakdown_angle * (1.0 / cap - 1.0) ** (1.0 / two_m) if cap < 1.0 else 0.0
        s[so + S_FILLER_NETWORK_CACHED_THRESHOLD_RAD] = threshold
    elongation = abs(centre_elongation)
    g_target = g_rec
    if elongation > s[so + S_FILLER_NETWORK_CACHED_THRESHOLD_RAD]:
        g_target = min(g_rec, 1.0 / (1.0 + (elongation / breakdown_angle) ** two_m))
    eo = so + S_FILLER_NETWORK_BLOCKS
    stored0 = s[so + S_STORED_ENERGY_J]
    torque0 = s[so + S_TORQUE_NM]
    # the network's stress relaxes about its rest state like the centre (a held twist becomes
    # unstrained): the elongations shrink by the centre's decay at the start of the step; the booked trapezoid adds (1 - relax) torque0 dx / 2 to the energy it releases, so
    # it is skipped in a step where that sum would be negative (a large step against the torque)
    relax = centre_decay
    if stored0 * (1.0 - relax * relax) + 0.5 * torque0 * (1.0 - relax) * dx < 0.0:
        relax = 1.0
    # recovery: re-formed bonds are unstrained, so the elongations shrink by g0 / g (the torque
    # g k e is kept, the stored energy falls) before the step's motion
    ratio = relax * (g0 / g_target if g_target > g0 else 1.0)
    ko = po + P_FILLER_NETWORK_TABLES  # k_1..k_n, then a_1..a_n
    force, energy = _filler_sliders(p[ko:ko + n], p[ko + n:ko + 2 * n], s[eo:eo + n], n, ratio, dx)
    g = g_target
    if g < g0 and 0.5 * (relax * torque0 + g * force) * dx - (g * energy - relax * relax * stored0) < 0.0:
        g = g0  # this step cannot book the breakdown with a non-negative balance: the next one will
    torque1 = g * force
    stored1 = g * energy
    s[so + S_DISSIPATED_ENERGY_J] += 0.5 * (torque0 + torque1) * dx - (stored1 - stored0)
    s[so + S_STORED_ENERGY_J] = stored1
    s[so + S_TORQUE_NM] = torque1
    s[so + S_FILLER_NETWORK_DAMAGE] = 1.0 - g
    s[so + S_FILLER_NETWORK_CENTRE_ELONGATION_RAD] = centre_elongation
    return torque1


# ---------------------------------------------------------------- the compiled coupling

@njit(inline="always", **JIT)
def large_strain_network(p, po, s, so, x0, x1, h):
    """One step of the large-strain network from x0 to x1 (rad) over h (s); returns its torque (N*m).

    What filled rubber shows at shear strains of order one (high-damping rubber bearings; the
    form of Grant, Fenves & Whittaker 2004, with an Iwan network for their Bouc-Wen variable;
    docs/theory.md#large-strain-network), three parts sharing one state:

    - **a stiffening spring softened by scragging**: (1 - D) (k x + a x |x|^q), the stiffening's
      onset and order set by a and q; the damage D (Mullins 1969; the scragging of isolator
      rubber) grows towards D_inf(x_max) = D_max (1 - exp(-(x_max / x_D)^r)), x_max the largest
      |x| yet seen, by the travel: dD = (D_inf - D) |dx| / L (exact for the step: D_inf - (D_inf
      - D) exp(-|dx| / L)); it never recovers (a scragged rubber stays scragged within a test);
    - **a stiffening friction network**: n Jenkins elements (springs k_n, slip limits s_i), its
      energy psi = H(x) sum k_n e_i^2 / 2 with H(x) = 1 + g x^2: the loss grows with the amplitude
      faster than one Coulomb bank (Grant, Fenves & Whittaker's (2004) (b1 + b2 |x|^2) z), and its torque
      d psi / dx = H k_n sum e_i + g x k_n sum e_i^2 is the gradient of a potential: the sliders,
      whose limits in force scale with H, slip at the elongations s_i whatever x (a return
      mapping, exact);
    - **the scragging's progress with the travel** (Gallardo et al. 2023's k_M): the spring's
      linear term times k_M = exp(-f c^p), c the travel sum |dx| from rest: a softening that goes
      on, ever slower, while the rubber is cycled, where D stops at D_inf(x_max) (f = 0: none);
    - **the friction's temporary hardening** (Gallardo et al. 2023's phi, set at each reversal by
      the excursion there): the slips s_i (1 + h r), r the |x| at the motion's last reversal: a
      half-cycle after a large excursion slips later (a larger loop force), one after a small
      excursion sooner (h = 0: none). Only the limits change at a reversal, not the elongations:
      no energy is created; a smaller limit clips the elongations (the energy released is dissipated);
    - **the scragging of each side** (Gallardo et al. 2023's Mullins strain per side; sides > 0):
      D and x_max of x < 0 in their own slots, those of x >= 0 in the shared ones (sides 0: one
      D for both). The spring's torque is 0 at x = 0, so the switch between them is continuous.

    Energy: the stored energy is psi plus the spring's (1 - D) (k x^2 / 2 + a |x|^(q+2) / (q+2));
    the dissipated energy is booked as the trapezoidal work of the step minus the change of the
    stored energy, so the books balance to round-off; what it books is the sliders' slip and the
    damage's released energy, plus the trapezoid's O(h^3) error on the nonlinear spring.

    params: [n, k, a, q, k_n, g, D_max, x_D, r, L, f, p, h, sides, s_1..s_n].
    internal (after the common header): [D, x_max, c, r, the motion's direction (+1, -1, 0 at rest),
    D and x_max of x < 0, e_1..e_n].
    """
    n = int(p[po + P_LARGE_STRAIN_NETWORK_N])
    dx = x1 - x0
    ax = abs(x1)
    slot_d = so + S_LARGE_STRAIN_NETWORK_DAMAGE
    slot_peak = so + S_LARGE_STRAIN_NETWORK_PEAK_ANGLE_RAD
    if p[po + P_LARGE_STRAIN_NETWORK_DAMAGE_SIDES] > 0.0 and x1 < 0.0:  # the negative side's own D, x_max
        slot_d = so + S_LARGE_STRAIN_NETWORK_DAMAGE_NEGATIVE
        slot_peak = so + S_LARGE_STRAIN_NETWORK_PEAK_NEGATIVE_ANGLE_RAD
    peak = s[slot_peak]
    if ax > peak:
        peak = ax
        s[slot_peak] = peak
    damage = s[slot_d]
    d_max = p[po + P_LARGE_STRAIN_NETWORK_DAMAGE_MAX]
    if d_max > 0.0 and dx != 0.0:
        d_inf = d_max * (1.0 - np.exp(-(peak / p[po + P_LARGE_STRAIN_NETWORK_DAMAGE_ANGLE])
                                      ** p[po + P_LARGE_STRAIN_NETWORK_DAMAGE_EXPONENT]))
        if damage < d_inf:
            damage = d_inf - (d_inf - damage) * np.exp(-abs(dx) / p[po + P_LARGE_STRAIN_NETWORK_DAMAGE_TRAVEL])
            s[slot_d] = damage
    travel = s[so + S_LARGE_STRAIN_NETWORK_TRAVEL_RAD] + abs(dx)
    s[so + S_LARGE_STRAIN_NETWORK_TRAVEL_RAD] = travel
    if dx != 0.0:
        direction = 1.0 if dx > 0.0 else -1.0
        if direction != s[so + S_LARGE_STRAIN_NETWORK_DIRECTION]:
            if s[so + S_LARGE_STRAIN_NETWORK_DIRECTION] != 0.0:  # a reversal at x0 (the first motion is none)
                s[so + S_LARGE_STRAIN_NETWORK_REVERSAL_ANGLE_RAD] = abs(x0)
            s[so + S_LARGE_STRAIN_NETWORK_DIRECTION] = direction
    k = p[po + P_LARGE_STRAIN_NETWORK_STIFFNESS]
    f_travel = p[po + P_LARGE_STRAIN_NETWORK_TRAVEL_SOFTENING]
    if f_travel > 0.0 and travel > 0.0:
        k *= np.exp(-f_travel * travel ** p[po + P_LARGE_STRAIN_NETWORK_TRAVEL_EXPONENT])
    a = p[po + P_LARGE_STRAIN_NETWORK_GAIN]
    q = p[po + P_LARGE_STRAIN_NETWORK_EXPONENT]
    hard = ax ** q if a != 0.0 else 0.0
    intact = 1.0 - damage
    torque = intact * (k + a * hard) * x1
    psi = intact * (0.5 * k * x1 * x1 + a * hard * x1 * x1 / (q + 2.0))
    kn = p[po + P_LARGE_STRAIN_NETWORK_NETWORK_STIFFNESS]
    if kn > 0.0:
        g = p[po + P_LARGE_STRAIN_NETWORK_FRICTION_GAIN]
        base = so + S_LARGE_STRAIN_NETWORK_BLOCKS
        limits = po + P_LARGE_STRAIN_NETWORK_TABLES
        r = s[so + S_LARGE_STRAIN_NETWORK_REVERSAL_ANGLE_RAD]
        widen = 1.0 + p[po + P_LARGE_STRAIN_NETWORK_SLIP_HARDENING] * r
        sum_e = 0.0
        sum_e2 = 0.0
        for i in range(n):
            e = s[base + i] + dx
            lim = p[limits + i] * widen
            if e > lim:
                e = lim
            elif e < -lim:
                e = -lim
            s[base + i] = e
            sum_e += e
            sum_e2 += e * e
        weight = 1.0 + g * x1 * x1
        torque += kn * (weight * sum_e + g * x1 * sum_e2)
        psi += 0.5 * kn * weight * sum_e2
    s[so + S_DISSIPATED_ENERGY_J] += 0.5 * (s[so + S_TORQUE_NM] + torque) * dx - (psi - s[so + S_STORED_ENERGY_J])
    s[so + S_STORED_ENERGY_J] = psi
    s[so + S_TORQUE_NM] = torque
    return torque


@njit(inline="always", **JIT)
def step_element(code, p, po, s, so, x0, x1, h):
    """Dispatch one kernel element (parameters from p[po], state from s[so])."""
    if code == LINEAR_SPRING:
        return linear_spring(p, po, s, so, x0, x1, h)
    if code == MAXWELL:
        return maxwell(p, po, s, so, x0, x1, h)
    if code == SLIDER_BANK:
        return slider_bank(p, po, s, so, x0, x1, h)
    if code == DASHPOT:
        return dashpot(p, po, s, so, x0, x1, h)
    if code == CUBIC_SPRING:
        return cubic_spring(p, po, s, so, x0, x1, h)
    if code == TABLE_SPRING:
        return table_spring(p, po, s, so, x0, x1, h)
    if code == VARIABLE_MAXWELL:
        return variable_maxwell(p, po, s, so, x0, x1, h)
    if code == PFEFFER:
        return pfeffer(p, po, s, so, x0, x1, h)
    if code == PAYNE:
        return payne(p, po, s, so, x0, x1, h)
    if code == FILLER_NETWORK:
        return filler_network(p, po, s, so, x0, x1, h)
    if code == MAXWELL_BANK:
        return maxwell_bank(p, po, s, so, x0, x1, h)
    if code == LARGE_STRAIN_NETWORK:
        return large_strain_network(p, po, s, so, x0, x1, h)
    return np.nan


@njit(inline="always", **JIT)
def step_instance(codes, p_off, s_off, params, state, x0, x1, h):
    """Advance every element of one instance; return the coupling torque (N*m)."""
    torque = 0.0
    for e in range(codes.size):
        torque += step_element(codes[e], params, p_off[e], state, s_off[e], x0, x1, h)
    return torque


def _run_history(codes, p_off, s_off, params, state, x_start, angles, h, torque, stored, dissipated,
                 record_energy):
    """Drive a batch through angle histories.

    angles (B, N) rad, starting from the committed angles x_start (B,); fills torque and, if
    ``record_energy``, stored and dissipated (B, N). ``state`` is advanced in place.
    """
    nb, nt = angles.shape
    shared = params.shape[0] == 1
    n_el = codes.size
    for b in range(nb):
        pb = params[0] if shared else params[b]
        sb = state[b]
        x0 = x_start[b]
        for n in range(nt):
            x1 = angles[b, n]
            torque[b, n] = step_instance(codes, p_off, s_off, pb, sb, x0, x1, h)
            x0 = x1
            if not record_energy:
                continue
            e_sum = 0.0
            d_sum = 0.0
            for e in range(n_el):
                e_sum += sb[s_off[e] + S_STORED_ENERGY_J]
                d_sum += sb[s_off[e] + S_DISSIPATED_ENERGY_J]
            stored[b, n] = e_sum
            dissipated[b, n] = d_sum


# One build: a large batch's history is spread over the cores by running chunks of its rows on
# threads (droptower.rheology.threads), not by a second, parallel build of the kernel.
run_history = njit(**row_loop_options(__file__), **JIT)(_run_history)

#: the energy records a step leaves empty
_NO_ENERGY = np.empty((0, 0))


def step_batch(codes, p_off, s_off, params, state, x0, x1, h, torque):
    """One step of a batch: params (B, P) or (1, P), state (B, S), x0, x1, torque (B,) (C-contiguous,
    writeable; torque is filled). A history of one sample: the one build of :func:`run_history`,
    as every kernel inlining the whole coupling step costs seconds of compilation per build."""
    run_history(codes, p_off, s_off, params, state, x0, x1.reshape(-1, 1), h, torque.reshape(-1, 1), _NO_ENERGY,
                _NO_ENERGY, False)

compile_once_across_processes(globals())  # a kernel no cache holds is compiled by one process at a time
