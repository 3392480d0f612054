"""Free flight: a scene between contacts, integrated without pymunk.

While the drop mass does not touch the lever, the scene of :mod:`.scene` is two independent
motions: the drop mass falls freely along its guide, and the lever swings on the coupling
(J phi'' = T_screw - T(phi), docs/theory.md#decay). pymunk integrates both by symplectic
Euler, positions first with the old velocities, then the velocities (Chipmunk's
``cpBodyUpdatePosition`` / ``cpBodyUpdateVelocity``; the guide and the pivot act on the
other coordinates only); :func:`fly` takes the very same steps, compiled, one row at a time,
and records the samples and energies :meth:`DropTowerScenes.run` records. Only contacts
need pymunk's solver: a row flies until its drop mass may come within :data:`MARGIN_M` of
the lever within the next :data:`ENTER_SAMPLES` output samples (:func:`clear_of`), and hands the scene back there.

The distance of the striker's centre from the lever's line (the lever turned by phi about
its pivot, the centre at height y above the pivot and L to its side) is
``gap = L sin(phi) + y cos(phi) - r``, its rate ``(L cos(phi) - y sin(phi)) w + v cos(phi)``, and
its second derivative is bounded by ``(L + |y|) (|alpha| + w^2) + g + 2 |v w|``: ``clear_of`` asks
for the gap to exceed the margin over the horizon with the second derivative at twice its bound.
"""
from __future__ import annotations

import math

from numba import njit

from droptower.rheology import kernels as K
from droptower.rheology.numba_cache import compile_once_across_processes

#: The gap (m) a scene in free flight keeps from a possible contact. Integrating the same steps,
#: flight and pymunk differ by rounding (1e-15 m); but pymunk must hold the pair a little before
#: it touches to resolve the contact exactly as it does when it held it all along (measured: handed
#: back 0.1 mm ahead, an impact came out different by up to 5e-7 of its torque; 0.3 mm ahead, by
#: 4e-10, the rounding by which a scene differs between batches of other sizes).
MARGIN_M = 3e-4
#: Output samples over which a flying scene must stay clear of the lever to go on flying.
ENTER_SAMPLES = 2


@njit(**K.JIT)
def clear_of(phi, w, alpha, y, v, lever_length_m, striker_radius_m, gravity_m_per_s2, horizon_s):
    """True if the striker (centre y above the pivot, velocity v) cannot come within
    :data:`MARGIN_M` of the lever (angle phi, rate w, angular acceleration alpha) within
    ``horizon_s`` (SI units)."""
    sin, cos = math.sin(phi), math.cos(phi)
    gap = lever_length_m * sin + y * cos - striker_radius_m
    rate = (lever_length_m * cos - y * sin) * w + v * cos
    accel = (lever_length_m + abs(y)) * (abs(alpha) + w * w) + gravity_m_per_s2 + 2.0 * abs(v * w)
    # gap(t) >= gap + rate t - accel t^2 (twice the bound), concave: least at either end
    return min(gap, gap + rate * horizon_s - accel * horizon_s * horizon_s) > MARGIN_M


@njit(**K.JIT)
def fly(codes, p_off, s_off, params, state, state_angle, state_torque, rows, start, stop, twist, screw, inertia,
        mass, phi, rate, y, v, torque, stored_idx, dissipated_idx, stored0, dissipated0, loss_total,
        lever_length_m, striker_radius_m, g, h, steps_per_sample, energy_every,
        angle_out, torque_out, mass_out, kinetic, potential, stored, dissipated, screw_work, loss):
    """Fly each row b of ``rows`` from the output sample ``start[j]`` until it may touch or the
    record ends; ``stop[j]`` gets the sample where it stopped (the record's length if it did not).

    Per row (B,): twist (rad, the coupling's angle at the lever's rest), screw (N*m), inertia
    (kg*m^2), mass (kg); phi, rate, y, v, torque carry the lever's angle (rad) and rate (rad/s),
    the striker's height above the pivot (m) and velocity (m/s, up), and the coupling torque
    (N*m) at the start (in place); ``state`` (B, S), ``state_angle``, ``state_torque`` the
    coupling's committed state (in place). Every sample reached is written to angle_out,
    torque_out, mass_out (B, N) (the drop mass's height) and every ``energy_every``-th one to
    the energies (B, M), as :meth:`DropTowerScenes.run` does; h: the internal step (s).
    """
    n_samples = angle_out.shape[1]
    shared = params.shape[0] == 1
    horizon = ENTER_SAMPLES * steps_per_sample * h
    for j in range(rows.size):
        b = rows[j]
        pb = params[0] if shared else params[b]
        sb = state[b]
        p, w, yy, vv, t = phi[b], rate[b], y[b], v[b], torque[b]
        x0, s_b, J = twist[b], screw[b], inertia[b]
        n = start[j]
        while n < n_samples:
            if not clear_of(p, w, (s_b - t) / J, yy, vv, lever_length_m, striker_radius_m, g, horizon):
                break
            angle_out[b, n] = p
            torque_out[b, n] = t
            mass_out[b, n] = yy
            if n % energy_every == 0:
                e = n // energy_every
                kinetic[b, e] = 0.5 * mass[b] * vv * vv + 0.5 * J * w * w
                potential[b, e] = mass[b] * g * (yy - striker_radius_m)
                es = 0.0
                for i in stored_idx:
                    es += sb[i]
                ed = 0.0
                for i in dissipated_idx:
                    ed += sb[i]
                stored[b, e] = es - stored0[b]
                dissipated[b, e] = ed - dissipated0[b]
                screw_work[b, e] = s_b * p
                loss[b, e] = loss_total[b]
            n += 1
            if n == n_samples:
                break  # the last sample's steps reach beyond the record: nothing records them
            for _ in range(steps_per_sample):
                p1 = p + w * h  # positions first, with the old velocities (as pymunk)
                t = K.step_instance(codes, p_off, s_off, pb, sb, x0 + p, x0 + p1, h)
                w += (s_b - t) / J * h
                p = p1
                yy += vv * h
                vv -= g * h
        phi[b], rate[b], y[b], v[b], torque[b] = p, w, yy, vv, t
        state_angle[b] = x0 + p
        state_torque[b] = t
        stop[j] = n

compile_once_across_processes(globals())  # a kernel no cache holds is compiled by one process at a time
