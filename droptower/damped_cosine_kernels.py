"""The compiled kernels of the decay fit (:func:`droptower.damped_cosine.fit_decay`): the normal equations
of φ̂·e^(−δt)·cos(ωt − Φ) in one pass and a Levenberg-Marquardt on them (Rapp et al. 2022, eq. 13-14).

A module of their own so that importing :mod:`droptower.damped_cosine` (every command that reads a log)
imports no numba: this one is imported when a fit first runs, and its kernels are loaded from the
package's cache (:mod:`droptower.rheology.numba_cache`) once per process.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from droptower.rheology.numba_cache import cache_available, compile_once_across_processes

_JIT = dict(cache=cache_available(), nogil=True, fastmath=False, error_model="numpy")


def normal_equations(p, t, y, a, g):
    """Sum of squares of decay(p, t) - y; fills a = JᵀJ (4, 4) and g = Jᵀr (4,) in one pass."""
    amp, delta, omega, phase = p[0], p[1], p[2], p[3]
    a[:] = 0.0
    g[:] = 0.0
    cost = 0.0
    col = np.empty(4)
    for i in range(t.size):
        e = math.exp(-delta * t[i])
        arg = omega * t[i] - phase
        c = e * math.cos(arg)
        s = e * math.sin(arg)
        r = amp * c - y[i]
        col[0] = c
        col[1] = -t[i] * amp * c
        col[2] = -t[i] * amp * s
        col[3] = amp * s
        cost += r * r
        for j in range(4):
            g[j] += col[j] * r
            for k in range(j + 1):
                a[j, k] += col[j] * col[k]
    for j in range(4):
        for k in range(j):
            a[k, j] = a[j, k]
    return cost


def solve_in_place(m, b):
    """Solve m x = b (n x n, n small) by Gaussian elimination with partial pivoting, the method of
    LAPACK's ``gesv`` (``np.linalg.solve``): m is overwritten, x is left in b. False where a pivot is
    zero (m singular). Written out because numba's binding of ``np.linalg.solve`` costs seconds of
    compilation for a 4 x 4 system."""
    n = b.size
    for k in range(n):
        pivot = k
        largest = abs(m[k, k])
        for i in range(k + 1, n):
            if abs(m[i, k]) > largest:
                pivot, largest = i, abs(m[i, k])
        if not largest > 0.0:
            return False
        if pivot != k:
            for j in range(n):
                m[k, j], m[pivot, j] = m[pivot, j], m[k, j]
            b[k], b[pivot] = b[pivot], b[k]
        for i in range(k + 1, n):
            f = m[i, k] / m[k, k]
            for j in range(k + 1, n):
                m[i, j] -= f * m[k, j]
            b[i] -= f * b[k]
    for k in range(n - 1, -1, -1):
        x = b[k]
        for j in range(k + 1, n):
            x -= m[k, j] * b[j]
        b[k] = x / m[k, k]
    return True


def levenberg_marquardt(t, y, x0, scale, tolerance, max_iterations):
    """The least-squares decay parameters from x0: Gauss-Newton steps, damped by Marquardt's
    (scaled) diagonal only where a step would raise the sum of squares. Returns (params, True)
    once no parameter moves by more than ``tolerance`` of its ``scale``, (x0, False) if that
    does not happen. (Element by element in loops: numba compiles numpy's array expressions
    for seconds, the loops in a fraction of that, with the same arithmetic.)"""
    p = x0.copy()
    a = np.empty((4, 4))
    g = np.empty(4)
    a_trial = np.empty((4, 4))
    g_trial = np.empty(4)
    a_scaled = np.empty((4, 4))
    g_scaled = np.empty(4)
    d = np.empty(4)
    m = np.empty((4, 4))
    step = np.empty(4)
    trial = np.empty(4)
    cost = normal_equations(p, t, y, a, g)
    lam = 0.0
    for _ in range(max_iterations):
        if not math.isfinite(cost):
            return x0, False
        for j in range(4):
            d[j] = math.sqrt(a[j, j])
            if not d[j] > 0.0:
                return x0, False
        for j in range(4):
            for k in range(4):
                a_scaled[j, k] = a[j, k] / (d[j] * d[k])
            g_scaled[j] = g[j] / d[j]
        while True:
            for j in range(4):
                for k in range(4):
                    m[j, k] = a_scaled[j, k]
                m[j, j] += lam
                step[j] = -g_scaled[j]
            if not solve_in_place(m, step):  # singular: MINPACK takes over
                return x0, False
            small = True
            for j in range(4):
                step[j] /= d[j]
                small = small and abs(step[j]) <= tolerance * scale[j]
                trial[j] = p[j] + step[j]
            cost_trial = normal_equations(trial, t, y, a_trial, g_trial)
            if cost_trial <= cost:
                break
            if small:  # at the minimum up to rounding
                return p, True
            lam = max(10.0 * lam, 1e-3)
            if lam > 1e10:
                return x0, False
        for j in range(4):
            p[j] = trial[j]
            g[j] = g_trial[j]
            for k in range(4):
                a[j, k] = a_trial[j, k]
        cost = cost_trial
        lam = 0.1 * lam if lam > 1e-6 else 0.0
        if small:
            return p, True
    return x0, False


normal_equations = njit(**_JIT)(normal_equations)
solve_in_place = njit(**_JIT)(solve_in_place)
levenberg_marquardt = njit(**_JIT)(levenberg_marquardt)

compile_once_across_processes(globals())  # a kernel no cache holds is compiled by one process at a time
