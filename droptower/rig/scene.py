"""The drop tower as a pymunk scene: many independent tests in one space, stepped together.

Each scene (Rapp et al. 2022, Fig. 5, docs/theory.md#rig): a lever on a pivot (PivotJoint to the static body)
with moment of inertia J about the pivot and its centre of gravity on the axis, so gravity
makes no torque; a drop mass with a round striker, guided vertically (GrooveJoint) above the
point at horizontal distance L from the axis. The lever's angle is the coupling's twist in the
direction the impact turns it (the tip points to -x, so the impact turns it counter-clockwise,
pymunk's positive sense).

Physics choices (the reasons are the rig's accuracy targets):

- SI units, gravity -g along y. ``collision_slop`` is 1 nm, far below the penetration of one
  step (v1 dt >= 0.3 m/s x 13 us = 4 um); pymunk's default (0.1 units) would be 100 mm.
- Restitution is set to k on the mass-lever arbiter in ``pre_solve``, every step of a contact
  (pymunk recomputes it each step as the product of the shapes' elasticities, left at 0 here,
  so a missed override would show as a plastic impact). The solver then enforces Newton's law
  on the normal relative velocity, which with the pivot gives docs/theory.md#impact.
- The coupling torque is applied to the lever at every internal step (pymunk clears
  ``Body.torque`` after each step). pymunk moves positions with the old velocity before it
  applies forces, so the torque is evaluated at the angle the step will reach,
  ``angle + rate dt``: the lever-coupling system is then integrated by symplectic Euler
  (stable for dt sqrt(K/J) < 2, energy error of order dt sqrt(K/J) / 2), one
  :meth:`Coupling.step` call for the whole batch per step.
- Every contact is counted: the ``begin`` callback opens an event (time), ``separate`` closes
  it; while contacts are open, pymunk's batch arbiter query after each step gives every
  impulse, and the kinetic energy each impulse removed follows from the velocities just after
  it minus the impulse's own velocity change (vectorised over the scenes in contact: an
  uncaught drop mass comes back and may rest on the lever for thousands of steps). The
  impulses are also booked on the output sample grid (``contact_impulse_ns``), each shared
  linearly between the two samples around the end of its step: the contact force history the
  impact-force sensor samples (:func:`droptower.rig.sensors.force_pulses`).
- An exception raised in a callback (a defect, or Ctrl-C arriving there) is raised where the
  step returns (:mod:`.callbacks`): cffi would print it and step on with the contact uncounted.
- Scenes sit 1 m apart along x: they never touch and share no body but the static one, so a
  scene in a batch moves as it would alone (up to rounding of its coordinates).
- A scene is in the space only around its contacts: between them its two bodies move
  independently and :mod:`.flight` takes the same steps compiled (:meth:`DropTowerScenes.run`),
  so pymunk steps only the scenes that are about to touch, touch, or have just separated.
"""
from __future__ import annotations

import copy
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import pymunk
import pymunk.batch

from droptower.rheology import Coupling, CouplingState
from droptower.rheology.kinds import DISSIPATED, STORED
from droptower.rig import flight
from droptower.rig.callbacks import raising_callback_errors

SPACING_M = 1.0          # distance between neighbouring scenes along x
LEVER_BODY_MASS_KG = 10.0  # translational mass of the lever; the pivot holds it, it never enters the result
TIP_MARGIN_M = 0.02      # lever line continues this far beyond the impact point
COLLISION_SLOP_M = 1e-9
MASS_TYPE, LEVER_TYPE = 1, 2
LEAVE_SAMPLES = 3        # a scene leaves the space when it stays clear of the lever this many samples (> flight.ENTER_SAMPLES)
FEW_SCENES = 8           # up to this many, body properties are read one by one (the batch API's fixed cost is higher)


@dataclass
class Contact:
    """One contact of the drop mass with the lever (from touching to separating).

    start_s: time of the step in which it began; steps: solver steps it lasted; impulse_ns:
    impulse on the drop mass over the whole contact (N*s); approach_m_per_s /
    separation_m_per_s: normal relative velocity just before and just after the impact (the
    first step that pushed; approach > 0); loss_j: kinetic energy the whole contact removed;
    drop_mass_after_m_per_s (positive down) and lever_rate_after_rad_per_s: velocities just
    after the impact.
    """

    start_s: float
    steps: int = 0
    impulse_ns: float = 0.0
    approach_m_per_s: float = float("nan")
    separation_m_per_s: float = float("nan")
    loss_j: float = 0.0
    drop_mass_after_m_per_s: float = float("nan")
    lever_rate_after_rad_per_s: float = float("nan")

    @property
    def restitution(self) -> float:
        """Effective restitution: separation / approach velocity."""
        return self.separation_m_per_s / self.approach_m_per_s


@dataclass
class SceneRecord:
    """What a batch of scenes did, sampled at the output rate.

    time_s (N,); angle_rad (B, N) lever rotation from its rest (pre-twisted) position;
    coupling_torque_nm (B, N) the coupling's torque (preload included); drop_mass_m (B, N)
    drop-mass position below the impact point (positive down). Energies (J) on the coarser grid
    ``energy_time_s`` (M,), each (B, M): kinetic (drop mass + lever), potential (drop mass,
    relative to the impact point), coupling stored and dissipated (changes since the start),
    screw_work (work of the preload screw on the lever), contact_loss (restitution losses).
    contact_impulse_ns (B, N): impulse of all contacts on the drop mass booked on the sample
    grid (N*s; impulses after the last sample go to it), so ``sum(contact_impulse_ns[i])`` is
    the sum of the impulses of ``contacts[i]``. contacts: per scene, its contacts in time order.
    """

    time_s: np.ndarray
    angle_rad: np.ndarray
    coupling_torque_nm: np.ndarray
    drop_mass_m: np.ndarray
    energy_time_s: np.ndarray
    kinetic_j: np.ndarray
    potential_j: np.ndarray
    stored_j: np.ndarray
    dissipated_j: np.ndarray
    screw_work_j: np.ndarray
    contact_loss_j: np.ndarray
    contact_impulse_ns: np.ndarray
    contacts: list[list[Contact]] = field(default_factory=list)


class _FewBodies:
    """Body state one property at a time: cheapest for a few scenes.

    masses, levers: the bodies of the scenes ``members`` (global scene indices), in that order.
    """

    def __init__(self, masses: list[pymunk.Body], levers: list[pymunk.Body], members: np.ndarray, batch: int):
        self.masses, self.levers = masses, levers
        self.local = np.full(batch, -1)
        self.local[members] = np.arange(len(members))

    def refresh(self) -> None:
        """Nothing to fetch: properties are read when asked for."""

    def predict(self, dt: float, twist: list[float], out: np.ndarray) -> None:
        """The coupling angle each lever will reach in the next step: twist + angle + rate dt."""
        for i, lever in enumerate(self.levers):
            out[i] = twist[i] + lever.angle + lever.angular_velocity * dt

    def state(self) -> tuple[list[float], list[float], list[float], list[float]]:
        """(lever angle, lever rate, drop-mass height, drop-mass vertical velocity), each per member."""
        return ([b.angle for b in self.levers], [b.angular_velocity for b in self.levers],
                [b.position.y for b in self.masses], [b.velocity.y for b in self.masses])

    def velocities(self, scenes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(drop-mass vertical velocity, lever rate) of the given scenes (global indices)."""
        local = self.local[scenes].tolist()
        return (np.array([self.masses[i].velocity.y for i in local]),
                np.array([self.levers[i].angular_velocity for i in local]))

    def apply_torque(self, screw: list[float], coupling_torque: np.ndarray) -> None:
        for lever, s, t in zip(self.levers, screw, coupling_torque.tolist()):
            lever.torque = s - t


class _ManyBodies:
    """Body state through pymunk's batch API: one C call for all bodies of the space."""

    FIELDS = (pymunk.batch.BodyFields.POSITION | pymunk.batch.BodyFields.ANGLE | pymunk.batch.BodyFields.VELOCITY
              | pymunk.batch.BodyFields.ANGULAR_VELOCITY)

    def __init__(self, space: pymunk.Space, masses: list[pymunk.Body], levers: list[pymunk.Body],
                 members: np.ndarray, batch: int):
        self.space = space
        ids = pymunk.batch.Buffer()
        pymunk.batch.get_space_bodies(space, pymunk.batch.BodyFields.BODY_ID, ids)
        where = {int(body_id): k for k, body_id in enumerate(np.frombuffer(ids.int_buf(), dtype=np.uintp))}
        self.mass_at = np.array([where[b.id] for b in masses])   # position of each member's bodies
        self.lever_at = np.array([where[b.id] for b in levers])  # in the space's body order
        self.local = np.full(batch, -1)
        self.local[members] = np.arange(len(members))
        self.buffer = pymunk.batch.Buffer()
        self.torque = np.zeros(len(where))
        self.torque_buffer = pymunk.batch.Buffer()
        self.torque_buffer.set_float_buf(self.torque)
        self.refresh()

    def refresh(self) -> None:
        """Fetch every body's state (after a step)."""
        self.buffer.clear()
        pymunk.batch.get_space_bodies(self.space, self.FIELDS, self.buffer)
        # per body: x, y, angle, vx, vy, angular velocity
        values = np.frombuffer(self.buffer.float_buf()).reshape(-1, 6)
        self.lever = values[self.lever_at]
        self.mass = values[self.mass_at]

    def predict(self, dt: float, twist: np.ndarray, out: np.ndarray) -> None:
        np.multiply(self.lever[:, 5], dt, out=out)
        out += self.lever[:, 2]
        out += twist

    def state(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        return self.lever[:, 2], self.lever[:, 5], self.mass[:, 1], self.mass[:, 4]

    def velocities(self, scenes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        local = self.local[scenes]
        return self.mass[local, 4], self.lever[local, 5]

    def apply_torque(self, screw: np.ndarray, coupling_torque: np.ndarray) -> None:
        self.torque[self.lever_at] = screw - coupling_torque
        pymunk.batch.set_space_bodies(self.space, pymunk.batch.BodyFields.TORQUE, self.torque_buffer)


class _Contacts:
    """Contact events of every scene, filled from pymunk's batch arbiter query.

    The current event of each scene lives in arrays (so many scenes in contact at once cost
    one vectorised update per step); :meth:`begin` closes the previous one into a
    :class:`Contact`.
    """

    FIELDS = (pymunk.batch.ArbiterFields.BODY_A_ID | pymunk.batch.ArbiterFields.TOTAL_IMPULSE
              | pymunk.batch.ArbiterFields.NORMAL | pymunk.batch.ArbiterFields.POINT_B_1)

    def __init__(self, space: pymunk.Space, masses: list[pymunk.Body], levers: list[pymunk.Body], pivot_x: np.ndarray,
                 mass_kg: np.ndarray, inertia_kgm2: np.ndarray, dt_s: float):
        self.space, self.dt = space, dt_s
        self.masses, self.levers = masses, levers
        ids = np.array([b.id for b in masses], dtype=np.uintp)
        self.sorted_ids = np.sort(ids)
        self.scene_of_sorted = np.argsort(ids)
        self.pivot_x, self.mass, self.inertia = pivot_x, mass_kg, inertia_kgm2
        b = len(masses)
        self.events: list[list[Contact]] = [[] for _ in range(b)]
        self.touching = np.zeros(b, bool)
        self.open = 0  # scenes in contact now
        self.loss_total = np.zeros(b)  # restitution losses of all contacts so far (J)
        self.buffer = pymunk.batch.Buffer()
        self.pending: tuple[np.ndarray, ...] | None = None
        self.history = np.zeros((b, 1))  # impulses on the output sample grid, sized by :meth:`start_history`
        # the current event per scene
        self.start = np.full(b, np.nan)
        self.steps = np.zeros(b, int)
        self.impulse = np.zeros(b)
        self.approach = np.full(b, np.nan)
        self.separation = np.full(b, np.nan)
        self.depth = np.zeros(b)  # how far the striker had passed the lever when the contact was found (m)
        self.loss = np.zeros(b)
        self.v_after = np.full(b, np.nan)
        self.w_after = np.full(b, np.nan)

    def _close(self, i: int) -> None:
        if np.isnan(self.start[i]):
            return
        self.events[i].append(Contact(
            start_s=float(self.start[i]), steps=int(self.steps[i]), impulse_ns=float(self.impulse[i]),
            approach_m_per_s=float(self.approach[i]), separation_m_per_s=float(self.separation[i]),
            loss_j=float(self.loss[i]), drop_mass_after_m_per_s=float(-self.v_after[i]),
            lever_rate_after_rad_per_s=float(self.w_after[i])))
        self.start[i] = np.nan

    def start_history(self, n_samples: int) -> None:
        """Book impulses from now on onto an empty grid of ``n_samples`` output samples."""
        self.history = np.zeros((len(self.events), n_samples))

    def begin(self, scene: int, time_s: float, depth_m: float = 0.0) -> None:
        self._close(scene)
        self.start[scene] = time_s
        self.depth[scene] = max(depth_m, 0.0)
        self.steps[scene] = 0
        self.impulse[scene] = self.loss[scene] = 0.0
        self.approach[scene] = self.separation[scene] = self.v_after[scene] = self.w_after[scene] = np.nan
        self.open += not self.touching[scene]
        self.touching[scene] = True

    def separate(self, scene: int) -> None:
        self.open -= bool(self.touching[scene])
        self.touching[scene] = False

    def query(self) -> None:
        """After a step with open contacts: keep the impulses of the arbiters that touched."""
        self.buffer.clear()
        pymunk.batch.get_space_arbiters(self.space, self.FIELDS, self.buffer)
        body = np.frombuffer(self.buffer.int_buf(), dtype=np.uintp)
        values = np.frombuffer(self.buffer.float_buf()).reshape(-1, 6)  # impulse xy, normal xy, point b xy
        scenes = self.scene_of_sorted[np.searchsorted(self.sorted_ids, body)]
        keep = self.touching[scenes]  # arbiters kept for persistence after separation report stale impulses
        self.pending = (scenes[keep], values[keep].copy())

    def account(self, bodies: _FewBodies | _ManyBodies, sample_position: float, step_samples: float) -> bool:
        """Book the pending impulses with the velocities just after them (the bodies' current state).

        sample_position: the end of the step that gave them, in output samples from the first;
        step_samples: one step in output samples. Returns True if it moved bodies (an impact's
        penetration removed: see :meth:`_undo_penetration`).
        """
        if self.pending is None:
            return False
        scenes, values = self.pending
        self.pending = None
        px, py, nx, ny, bx, by = values.T
        v_after, w_after = bodies.velocities(scenes)
        m, J = self.mass[scenes], self.inertia[scenes]
        rx, ry = bx - self.pivot_x[scenes], by  # lever arm of the contact point about the axis
        # velocities just before the impulse; the guide's and pivot's impulses do no work
        v_before = v_after - py / m
        w_before = w_after + (rx * py - ry * px) / J  # the lever gets -P at r
        pushed = (px != 0.0) | (py != 0.0)

        def normal_velocity(v, w):  # lever contact point relative to the drop mass, along the normal
            return -w * ry * nx + (w * rx - v) * ny

        loss = np.where(pushed, 0.5 * m * (v_before ** 2 - v_after ** 2) + 0.5 * J * (w_before ** 2 - w_after ** 2), 0.0)
        self.steps[scenes] += 1
        np.add.at(self.loss, scenes, loss)
        np.add.at(self.loss_total, scenes, loss)
        impulse = np.hypot(px, py)
        np.add.at(self.impulse, scenes, impulse)
        # the impact: the first step of the contact that pushed (the solver resolves it within the step)
        first = pushed & np.isnan(self.approach[scenes])
        hit = scenes[first]
        self.approach[hit] = -normal_velocity(v_before, w_before)[first]
        self.separation[hit] = normal_velocity(v_after, w_after)[first]
        self.v_after[hit] = v_after[first]
        self.w_after[hit] = w_after[first]
        # how long before the step's end the striker touched: the test's impact only (its first
        # contact) and an overlap reached in the last step; later, slow contacts are left alone
        tau = np.zeros(scenes.size)
        if hit.size:
            t = self.depth[hit] / self.approach[hit]
            impact = np.array([not self.events[i] for i in hit.tolist()])
            tau[first] = np.where(impact & (t > 0) & (t <= self.dt * (1 + 1e-9)), t, 0.0)
            self._undo_penetration(hit, tau[first], (v_after - v_before)[first], (w_after - w_before)[first])
        # shared between the samples around the impulse's time (the step's end, or an impact's
        # touch, where the bodies' motion now starts): sum and centroid (the timing) stay exact
        n = self.history.shape[1]
        position = sample_position - tau / self.dt * step_samples
        lo = np.minimum(position.astype(int), n - 1)
        share = np.where(lo + 1 < n, position - lo, 0.0)
        np.add.at(self.history, (scenes, lo), (1.0 - share) * impulse)
        np.add.at(self.history, (scenes, np.minimum(lo + 1, n - 1)), share * impulse)
        return bool(hit.size)

    def _undo_penetration(self, scenes: np.ndarray, tau_s: np.ndarray, dv: np.ndarray, dw: np.ndarray) -> None:
        """Move the bodies of an impact to where an exact (event-driven) impact leaves them.

        The contact is found after the step that carried the striker ``depth`` past the lever,
        tau = depth / approach velocity after the touch; the impulse then changes the velocities
        but not the positions, so every later contact would come about tau early (21-77 us
        here). Each body moves by its velocity change times tau (drop mass along the guide,
        lever about its axis): the pair then separates by k * depth, as if the impact had
        happened at the touch.
        """
        for i, tau, dvi, dwi in zip(scenes.tolist(), tau_s.tolist(), dv.tolist(), dw.tolist()):
            if not tau > 0:
                continue
            mass, lever = self.masses[i], self.levers[i]
            mass.position = (mass.position.x, mass.position.y + dvi * tau)
            lever.angle = lever.angle + dwi * tau

    def close_all(self) -> list[list[Contact]]:
        for i in range(len(self.events)):
            self._close(i)
        return self.events


class DropTowerScenes:
    """B drop tests in one pymunk space.

    inertia_kgm2, drop_mass_kg (B,): the lever's moment about its axis and the drop mass;
    gap_m, start_velocity_m_per_s (B,): the drop mass's start, above the impact point (it is
    released from its drop height earlier; the scene starts at the beginning of the record);
    lever_length_m, restitution, striker_radius_m, gravity_m_per_s2: the rig;
    dt_s: internal step; solver_iterations: pymunk impulse-solver passes; t0_s: time of the start.
    """

    def __init__(self, *, inertia_kgm2: np.ndarray, drop_mass_kg: np.ndarray, gap_m: np.ndarray,
                 start_velocity_m_per_s: np.ndarray, lever_length_m: float, restitution: float,
                 striker_radius_m: float, gravity_m_per_s2: float, dt_s: float, solver_iterations: int,
                 t0_s: float):
        self.inertia = np.asarray(inertia_kgm2, float)
        self.mass = np.asarray(drop_mass_kg, float)
        self.batch = self.inertia.size
        self.L = float(lever_length_m)
        self.g = float(gravity_m_per_s2)
        self.dt = float(dt_s)
        self.t0 = float(t0_s)
        self.time_s = self.t0
        self.r = float(striker_radius_m)

        space = pymunk.Space()
        space.gravity = (0.0, -self.g)
        space.iterations = int(solver_iterations)
        space.collision_slop = COLLISION_SLOP_M
        self.space = space
        self.masses: list[pymunk.Body] = []
        self.levers: list[pymunk.Body] = []
        self.parts: list[tuple] = []  # each scene's bodies, shapes and joints (added while it needs pymunk)
        scene_of: dict[pymunk.Shape, int] = {}
        pivot_x = SPACING_M * np.arange(self.batch)
        for i, x0 in enumerate(pivot_x.tolist()):
            lever = pymunk.Body(LEVER_BODY_MASS_KG, float(self.inertia[i]))
            lever.position = (x0, 0.0)
            line = pymunk.Segment(lever, (-self.L - TIP_MARGIN_M, 0.0), (TIP_MARGIN_M, 0.0), 0.0)
            line.collision_type = LEVER_TYPE
            pivot = pymunk.PivotJoint(space.static_body, lever, (x0, 0.0))
            mass = pymunk.Body(float(self.mass[i]), float("inf"))  # no rotation
            mass.position = (x0 - self.L, self.r + float(gap_m[i]))
            mass.velocity = (0.0, -float(start_velocity_m_per_s[i]))
            striker = pymunk.Circle(mass, self.r)
            striker.collision_type = MASS_TYPE
            top = self.r + 2.0 * float(gap_m[i]) + 1.0
            guide = pymunk.GrooveJoint(space.static_body, mass, (x0 - self.L, -1.0), (x0 - self.L, top), (0.0, 0.0))
            space.add(mass, striker, lever, line, pivot, guide)
            self.parts.append((mass, striker, lever, line, pivot, guide))
            self.masses.append(mass)
            self.levers.append(lever)
            scene_of[striker] = i
        self.contacts = _Contacts(space, self.masses, self.levers, pivot_x, self.mass, self.inertia, self.dt)

        def begin(arbiter: pymunk.Arbiter, space: pymunk.Space, data) -> None:
            points = arbiter.contact_point_set.points  # distance < 0: the striker overlaps the lever
            self.contacts.begin(scene_of[arbiter.shapes[0]], self.time_s, -points[0].distance if points else 0.0)

        def separate(arbiter: pymunk.Arbiter, space: pymunk.Space, data) -> None:
            self.contacts.separate(scene_of[arbiter.shapes[0]])

        k = float(restitution)

        def pre_solve(arbiter: pymunk.Arbiter, space: pymunk.Space, data) -> None:
            arbiter.restitution = k  # exactly k for the pair, not a product of elasticities

        space.on_collision(MASS_TYPE, LEVER_TYPE, begin=begin, pre_solve=pre_solve, separate=separate)
        self.in_space = np.ones(self.batch, bool)
        self.bodies = self._bodies(np.arange(self.batch))

    def _bodies(self, members: np.ndarray) -> _FewBodies | _ManyBodies:
        masses, levers = [self.masses[i] for i in members], [self.levers[i] for i in members]
        if len(members) <= FEW_SCENES:
            return _FewBodies(masses, levers, members, self.batch)
        return _ManyBodies(self.space, masses, levers, members, self.batch)

    def _move(self, scenes: np.ndarray, into_space: bool) -> None:
        """Add the scenes to the space (pymunk integrates them) or take them out (they fly)."""
        for i in scenes.tolist():
            (self.space.add if into_space else self.space.remove)(*self.parts[i])
        self.in_space[scenes] = into_space

    def run(self, coupling: Coupling, state: CouplingState, pretwist_rad: np.ndarray, screw_nm: np.ndarray,
            n_samples: int, steps_per_sample: int, energy_every: int, fly_between_contacts: bool = True) -> SceneRecord:
        """Step ``n_samples * steps_per_sample`` times; sample every ``steps_per_sample`` steps.

        ``state`` is the coupling state at the twist ``pretwist_rad`` (B,); the screw holds the
        lever with the constant torque ``screw_nm`` (B,). Energies are sampled every
        ``energy_every`` output samples.

        A scene is in pymunk's space only around its contacts: between them it flies
        (:mod:`.flight`, the same steps compiled), from the start until its drop mass may come
        within :data:`~droptower.rig.flight.MARGIN_M` of the lever in the next sample, and again
        from a sample where it touches nothing and stays clear for :data:`LEAVE_SAMPLES` samples.
        ``fly_between_contacts=False`` keeps every scene in the space all along (the reference
        the flight is tested against).
        """
        with raising_callback_errors() as check:  # a Ctrl-C or defect in a callback stops the run (.callbacks)
            return self._run(coupling, state, pretwist_rad, screw_nm, n_samples, steps_per_sample, energy_every,
                             fly_between_contacts, check)

    def _run(self, coupling: Coupling, state: CouplingState, pretwist_rad: np.ndarray, screw_nm: np.ndarray,
             n_samples: int, steps_per_sample: int, energy_every: int, fly_between_contacts: bool,
             check: Callable[[], None]) -> SceneRecord:
        B, dt, sps = self.batch, self.dt, steps_per_sample
        n_energy = (n_samples - 1) // energy_every + 1
        angle = np.empty((B, n_samples))
        torque_hist = np.empty((B, n_samples))
        mass_hist = np.empty((B, n_samples))
        kinetic, potential, stored, dissipated, screw_work, loss = (np.empty((B, n_energy)) for _ in range(6))
        stored0 = coupling.stored_energy(state)
        dissipated0 = coupling.dissipated_energy(state)
        twist = np.ascontiguousarray(pretwist_rad, float)
        screw = np.ascontiguousarray(screw_nm, float)
        contacts = self.contacts
        contacts.start_history(n_samples)
        step_samples = 1.0 / sps
        # what a flying scene carries: lever angle and rate, drop-mass height and velocity, torque
        phi = np.array([b.angle for b in self.levers])
        rate = np.array([b.angular_velocity for b in self.levers])
        y = np.array([b.position.y for b in self.masses])
        v = np.array([b.velocity.y for b in self.masses])
        torque = state.torque_nm.copy()
        stop = np.zeros(B, np.int64)  # the sample where each scene's flight stopped (n_samples: the record's end)
        slots = coupling.s_off[:-1]
        stored_idx, dissipated_idx = (np.ascontiguousarray(slots + k, np.int64) for k in (STORED, DISSIPATED))
        horizon_leave = LEAVE_SAMPLES * sps * dt

        def fly(scenes: np.ndarray, n: int) -> None:
            rows = np.ascontiguousarray(scenes, np.int64)
            out = np.empty(rows.size, np.int64)
            flight.fly(coupling.codes, coupling.p_off, coupling.s_off, coupling.params, state.values, state.angle_rad,
                       state.torque_nm, rows, np.full(rows.size, n, np.int64), out, twist, screw, self.inertia,
                       self.mass, phi, rate, y, v, torque, stored_idx, dissipated_idx, stored0, dissipated0,
                       contacts.loss_total, self.L, self.r, self.g, dt, sps, energy_every,
                       angle, torque_hist, mass_hist, kinetic, potential, stored, dissipated, screw_work, loss)
            stop[scenes] = out

        self._move(np.flatnonzero(self.in_space), False)
        if fly_between_contacts:
            fly(np.arange(B), 0)
        members = np.empty(0, int)  # the scenes in the space, while it does not change:
        bodies: _FewBodies | _ManyBodies | None = None
        sub: CouplingState | None = None  # their coupling state,
        sub_coupling = coupling           # parameters,
        sub_torque = np.empty(0)          # torque,
        twist_arg: np.ndarray | list[float] = []
        screw_arg: np.ndarray | list[float] = []
        pred = np.empty(0)

        def regroup(leaving: np.ndarray, entering: np.ndarray) -> None:
            """Scenes leave the space (their state goes to the flight carriers) or enter it."""
            nonlocal members, bodies, sub, sub_coupling, sub_torque, twist_arg, screw_arg, pred
            if sub is not None:  # the members' coupling state back into the batch's
                state.merge(members, sub)
                torque[members] = sub_torque
            if leaving.size:
                local = bodies.local[leaving]
                lever_angle, lever_rate, mass_y, mass_v = (np.asarray(a)[local] for a in bodies.state())
                phi[leaving], rate[leaving], y[leaving], v[leaving] = lever_angle, lever_rate, mass_y, mass_v
                self._move(leaving, False)
            for i in entering.tolist():  # where its flight stopped
                lever, mass = self.levers[i], self.masses[i]
                lever.angle, lever.angular_velocity = float(phi[i]), float(rate[i])
                mass.position = (mass.position.x, float(y[i]))
                mass.velocity = (mass.velocity.x, float(v[i]))
            self._move(entering, True)
            members = np.flatnonzero(self.in_space)
            if not members.size:
                bodies = sub = None
                return
            bodies = self._bodies(members)
            sub = state.take(members)
            sub_coupling = coupling
            if coupling.n_sets > 1:
                sub_coupling = copy.copy(coupling)
                sub_coupling.params = coupling.params[members]
            sub_torque = torque[members]
            few = isinstance(bodies, _FewBodies)
            twist_arg, screw_arg = (twist[members].tolist(), screw[members].tolist()) if few else \
                (twist[members], screw[members])
            pred = np.empty(members.size)

        n = 0
        while n < n_samples:
            entering = np.flatnonzero(~self.in_space & (stop == n))
            if entering.size:
                regroup(np.empty(0, int), entering)
            if not members.size:  # every scene flies: on to the next that stops
                n = int(stop.min())
                continue
            for s in range(sps):
                k = n * sps + s
                bodies.refresh()
                if contacts.pending is not None and contacts.account(bodies, k / sps, step_samples):
                    bodies.refresh()  # an impact moved bodies
                if s == 0:
                    lever_angle, lever_rate, mass_y, mass_v = (np.asarray(a) for a in bodies.state())
                    clear = [fly_between_contacts and not contacts.touching[i] and flight.clear_of(
                        a, w, (sc - t) / J, yy, u, self.L, self.r, self.g, horizon_leave)
                        for i, a, w, yy, u, sc, t, J in zip(
                            members.tolist(), lever_angle.tolist(), lever_rate.tolist(), mass_y.tolist(),
                            mass_v.tolist(), screw[members].tolist(), sub_torque.tolist(),
                            self.inertia[members].tolist())]
                    if any(clear):
                        leaving = members[np.array(clear)]
                        regroup(leaving, np.empty(0, int))
                        fly(leaving, n)
                        back = leaving[stop[leaving] == n]  # not clear for the flight's own horizon after all
                        if back.size:
                            regroup(np.empty(0, int), back)
                        if not members.size:
                            break
                        lever_angle, lever_rate, mass_y, mass_v = (np.asarray(a) for a in bodies.state())
                    angle[members, n] = lever_angle
                    torque_hist[members, n] = sub_torque  # the torque at this angle (from the previous step)
                    mass_hist[members, n] = mass_y
                    if n % energy_every == 0:
                        e = n // energy_every
                        mass_kg, inertia = self.mass[members], self.inertia[members]
                        kinetic[members, e] = 0.5 * mass_kg * mass_v ** 2 + 0.5 * inertia * lever_rate ** 2
                        potential[members, e] = mass_kg * self.g * (mass_y - self.r)
                        stored[members, e] = coupling.stored_energy(sub) - stored0[members]
                        dissipated[members, e] = coupling.dissipated_energy(sub) - dissipated0[members]
                        screw_work[members, e] = screw[members] * lever_angle
                        loss[members, e] = contacts.loss_total[members]
                # the coupling angle this step will reach (pymunk moves positions first, with the old rate)
                bodies.predict(dt, twist_arg, pred)
                sub_torque = sub_coupling.step(sub, pred, dt)
                bodies.apply_torque(screw_arg, sub_torque)
                self.time_s = self.t0 + (k + 1) * dt  # the end of this step: contacts are stamped with it
                self.space.step(dt)
                check()
                if contacts.open:
                    contacts.query()
            n += 1
        if members.size:
            bodies.refresh()
            contacts.account(bodies, n_samples, step_samples)
            regroup(np.empty(0, int), np.empty(0, int))  # the members' coupling state back into the batch's
        time_s = self.t0 + np.arange(n_samples) * sps * dt
        return SceneRecord(time_s=time_s, angle_rad=angle, coupling_torque_nm=torque_hist, drop_mass_m=self.r - mass_hist,
                           energy_time_s=time_s[::energy_every], kinetic_j=kinetic, potential_j=potential,
                           stored_j=stored, dissipated_j=dissipated, screw_work_j=screw_work, contact_loss_j=loss,
                           contact_impulse_ns=contacts.history, contacts=contacts.close_all())
