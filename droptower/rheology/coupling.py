"""A coupling: a parallel composition of elements, compiled, with explicit state and time step.

The discipline follows OpenSees' uniaxial materials without their global time step: the
caller owns a :class:`CouplingState` (the committed state of a whole batch), asks for the
torque at a trial angle with :meth:`Coupling.trial` (committed state untouched), and keeps
the result with :meth:`CouplingState.commit` — or does both at once with
:meth:`Coupling.step`. Every call takes its own time step ``dt_s``. The leading axis of
every array is the batch: many rigs, or many parameter sets (:meth:`Coupling.stack`), advance
in one call.
"""
from __future__ import annotations

import copy

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from droptower.errors import DroptowerError, expects, finite_values
from droptower.limits import MAX_COUPLING_STATE
from droptower.rheology import kernels as K
from droptower.rheology.elements import ElementSpec, KernelElement
from droptower.rheology.kinds import DISSIPATED, STORED, Motion, kind_of
from droptower.rheology.threads import run_rows


@dataclass
class CouplingState:
    """Committed state of a batch of coupling instances.

    values: (B, S) element states (see :mod:`.kernels` for the layout); angle_rad (B,) the
    committed angle; torque_nm (B,) the torque at that angle.
    """

    values: np.ndarray
    angle_rad: np.ndarray
    torque_nm: np.ndarray
    _trial: "CouplingState | None" = field(default=None, repr=False)

    @property
    def batch(self) -> int:
        return self.values.shape[0]

    def copy(self) -> "CouplingState":
        """An independent copy of the committed state (a pending trial is not carried)."""
        return CouplingState(self.values.copy(), self.angle_rad.copy(), self.torque_nm.copy())

    def take(self, rows: np.ndarray) -> "CouplingState":
        """The committed state of some rows of the batch, as an independent state (copies).

        rows: integer indices (repeats allowed: one row may start several) or a boolean mask of
        the batch. Advance the result on its own and put it back with :meth:`merge`.
        """
        return CouplingState(self.values[rows], self.angle_rad[rows], self.torque_nm[rows])

    def merge(self, rows: np.ndarray, part: "CouplingState") -> None:
        """Set the rows ``rows`` of this state to ``part``'s (in place; one row of ``part`` per
        selected row, in order): the inverse of :meth:`take` for a part advanced on its own."""
        self.values[rows] = part.values
        self.angle_rad[rows] = part.angle_rad
        self.torque_nm[rows] = part.torque_nm

    def commit(self) -> None:
        """Make the last trial (:meth:`Coupling.trial`) the committed state."""
        if self._trial is None:
            raise RuntimeError("commit() without a trial")
        self.values[...] = self._trial.values
        self.angle_rad[...] = self._trial.angle_rad
        self.torque_nm[...] = self._trial.torque_nm
        self._trial = None

    def revert(self) -> None:
        """Forget the last trial."""
        self._trial = None


@dataclass(frozen=True)
class Response:
    """Histories from :meth:`Coupling.simulate`, each (B, N) or (N,) like the input angle.

    torque_nm: coupling torque; stored_energy_j, dissipated_energy_j: energy stored in the
    springs and dissipated since the start; state: the committed state at the end.
    """

    torque_nm: np.ndarray
    stored_energy_j: np.ndarray
    dissipated_energy_j: np.ndarray
    state: CouplingState


class Coupling:
    """A compiled coupling model (a parallel composition of elements).

    Build it with :func:`droptower.load_coupling` from a TOML file or from element specs
    (``Coupling([spec, ...])``). ``params`` has one row per parameter set; one row is shared
    by the whole batch.
    """

    @expects(elements=["droptower.rheology.elements.ElementSpec"])
    def __init__(self, elements: list[ElementSpec], *, name: str = "", description: str = "",
                 source: str = "", units: str = "torsional", path: Path | None = None,
                 params: np.ndarray | None = None):
        self._build(elements, [el.compile() for el in elements], params, name, description, source, units, path)

    def _build(self, elements: list[ElementSpec], compiled: list[list[KernelElement]], params: np.ndarray | None,
               name: str, description: str, source: str, units: str, path: Path | None) -> None:
        """The coupling of ``elements`` compiled into ``compiled`` (each element's kernel
        elements), with the parameter sets ``params`` (None: the kernels' own, one set)."""
        if not elements:
            raise DroptowerError("a coupling needs at least one element", file=path)
        self.elements = list(elements)
        self.name = name
        self.description = description
        self.source = source
        self.units = units
        self.path = path
        kernels = [k for ks in compiled for k in ks]
        owner = [i for i, ks in enumerate(compiled) for _ in ks]
        self.kernels = kernels
        self.kernel_owner = np.asarray(owner)
        self.codes = np.array([k.code for k in kernels], dtype=np.int64)
        self.p_off = np.concatenate([[0], np.cumsum([k.params.size for k in kernels])]).astype(np.int64)
        self.s_off = np.concatenate([[0], np.cumsum([k.n_state for k in kernels])]).astype(np.int64)
        if self.s_off[-1] > MAX_COUPLING_STATE:
            raise DroptowerError(f"{self.s_off[-1]} state variables per instance exceed the limit of "
                                 f"{MAX_COUPLING_STATE} (run time and memory grow with them): use fewer or smaller "
                                 "discretised elements", file=path)
        default = np.concatenate([k.params for k in kernels])[None, :].astype(np.float64)
        self.params = default if params is None else np.ascontiguousarray(params, dtype=np.float64)
        if self.params.ndim != 2 or self.params.shape[1] != default.shape[1]:
            raise ValueError("params must have shape (n_sets, %d)" % default.shape[1])

    @classmethod
    def compiled(cls, elements: list[ElementSpec], kernels: list[list[KernelElement]], params: np.ndarray, *,
                 name: str = "", description: str = "", source: str = "", units: str = "torsional",
                 path: Path | None = None) -> "Coupling":
        """The coupling of validated ``elements`` already compiled (``kernels``: each element's
        kernel elements, what its ``compile()`` returned) with the parameter sets ``params``
        (n_sets, P): what ``Coupling(elements, ..., params=params)`` builds, without compiling
        the elements again (the identification builds one per core call from elements it
        compiled before, :mod:`droptower.identify.families.compiled`)."""
        out = cls.__new__(cls)
        out._build(elements, kernels, params, name, description, source, units, path)
        return out

    # ------------------------------------------------------------- structure
    @property
    def n_state(self) -> int:
        return int(self.s_off[-1])

    @property
    def n_sets(self) -> int:
        """Number of parameter sets (rows of ``params``); 1 means shared by the whole batch."""
        return self.params.shape[0]

    def with_params(self, params: np.ndarray) -> "Coupling":
        """This coupling's compiled structure with other parameter rows ``params`` (n_sets, P): no
        re-compilation of its elements (what building a :class:`Coupling` anew costs per call)."""
        params = np.ascontiguousarray(params, dtype=np.float64)
        if params.ndim != 2 or params.shape[1] != self.params.shape[1]:
            raise ValueError("params must have shape (n_sets, %d)" % self.params.shape[1])
        out = copy.copy(self)
        out.params = params
        return out

    @staticmethod
    def stack(couplings: list["Coupling"]) -> "Coupling":
        """One coupling whose batch rows are the given couplings (same element structure)."""
        first = couplings[0]
        for c in couplings[1:]:
            if not (np.array_equal(c.codes, first.codes) and np.array_equal(c.p_off, first.p_off)
                    and np.array_equal(c.s_off, first.s_off)):
                raise DroptowerError("couplings to stack must have the same element structure", file=c.path)
        # the first's compiled layout, not its elements compiled again (the same numbers)
        out = first.with_params(np.vstack([c.params for c in couplings]))
        out.elements, out.kernels = list(first.elements), list(first.kernels)
        return out

    def _check_batch(self, batch: int) -> None:
        if self.n_sets not in (1, batch):
            raise ValueError(f"batch of {batch} does not match {self.n_sets} parameter sets")

    # ------------------------------------------------------------- stepping
    def new_state(self, batch: int | None = None) -> CouplingState:
        """A virgin state at angle 0: every spring relaxed, nothing stored or dissipated."""
        batch = self.n_sets if batch is None else batch
        self._check_batch(batch)
        return CouplingState(np.zeros((batch, self.n_state)), np.zeros(batch), np.zeros(batch))

    def trial(self, state: CouplingState, angle_rad: np.ndarray | float, dt_s: float) -> np.ndarray:
        """Torque (N*m, shape (B,)) at the trial angle after ``dt_s`` seconds; the committed
        state is left untouched until :meth:`CouplingState.commit`."""
        _check_dt(dt_s)
        trial = state.copy()
        x1 = np.broadcast_to(np.asarray(angle_rad, np.float64), (state.batch,)).copy()
        self._check_batch(state.batch)
        K.step_batch(self.codes, self.p_off, self.s_off, self.params, trial.values, state.angle_rad, x1,
                     float(dt_s), trial.torque_nm)
        trial.angle_rad[...] = x1
        state._trial = trial
        return trial.torque_nm.copy()

    def step(self, state: CouplingState, angle_rad: np.ndarray | float, dt_s: float) -> np.ndarray:
        """Advance the committed state to ``angle_rad`` over ``dt_s`` seconds (trial + commit).

        Returns the torque at the new angle (N*m, shape (B,)). This is the call a simulation
        makes once per time step.
        """
        if not dt_s > 0.0:  # also catches NaN; cheap enough for the hot path
            _check_dt(dt_s)
        x1 = angle_rad
        if not (type(x1) is np.ndarray and x1.dtype == np.float64 and x1.shape == (state.batch,)
                and x1.flags.c_contiguous and x1.flags.writeable):  # the hot path (once per time step)
            # a copy, not a view: a broadcast scalar (batch 1) is a read-only contiguous view, and a
            # read-only argument is another signature numba compiles the whole step kernel for
            x1 = np.broadcast_to(np.asarray(angle_rad, np.float64), (state.batch,)).copy()
        K.step_batch(self.codes, self.p_off, self.s_off, self.params, state.values, state.angle_rad,
                     x1, float(dt_s), state.torque_nm)
        state.angle_rad[...] = x1
        return state.torque_nm.copy()

    def simulate(self, angle_rad: np.ndarray, dt_s: float, state: CouplingState | None = None,
                 record_energy: bool = True) -> Response:
        """Drive the coupling through an angle history sampled every ``dt_s`` seconds.

        ``angle_rad`` is (N,) or (B, N). Sample n is reached from sample n-1 (the first from
        the state's angle, 0 for a fresh state) with the angle linear in between. A given
        ``state`` is advanced in place; by default a fresh one is used. Without
        ``record_energy`` the energy histories of the response are empty.
        """
        _check_dt(dt_s)
        x = finite_values(angle_rad, "angle_rad")  # the angle history
        single = x.ndim == 1
        x2 = np.ascontiguousarray(np.atleast_2d(x))
        if x2.ndim != 2:
            raise ValueError("angle_rad must be (N,) or (B, N)")
        if state is None:
            state = self.new_state(max(x2.shape[0], 1) if self.n_sets == 1 else self.n_sets)
        if x2.shape[0] == 1 and state.batch > 1:
            x2 = np.ascontiguousarray(np.broadcast_to(x2, (state.batch, x2.shape[1])))
        if x2.shape[0] != state.batch:
            raise ValueError(f"angle history has {x2.shape[0]} rows, state has batch {state.batch}")
        self._check_batch(state.batch)
        torque = np.empty_like(x2)
        stored = np.empty_like(x2) if record_energy else np.empty((0, 0))
        dissipated = np.empty_like(x2) if record_energy else np.empty((0, 0))
        # the arguments at positions 3-6 and 8-10 have one row per row of the batch (params unless shared)
        run_rows(K.run_history, (self.codes, self.p_off, self.s_off, self.params, state.values, state.angle_rad.copy(),
                                 x2, float(dt_s), torque, stored, dissipated, record_energy),
                 (3, 4, 5, 6, 8, 9, 10), state.batch)
        if x2.shape[1]:
            state.angle_rad[...] = x2[:, -1]
            state.torque_nm[...] = torque[:, -1]
        if single and state.batch == 1:
            torque = torque[0]
            if record_energy:
                stored, dissipated = stored[0], dissipated[0]
        return Response(torque, stored, dissipated, state)

    def respond(self, angle_rad: np.ndarray, dt_s: float) -> np.ndarray:
        """Torque (N*m) for a prescribed angle history (rad) from a fresh state."""
        return self.simulate(angle_rad, dt_s, record_energy=False).torque_nm

    # ------------------------------------------------------------- energy
    def stored_energy(self, state: CouplingState) -> np.ndarray:
        """Energy stored in the springs (J, shape (B,))."""
        return state.values[:, self.s_off[:-1] + STORED].sum(axis=1)

    def dissipated_energy(self, state: CouplingState) -> np.ndarray:
        """Energy dissipated since the state was created (J, shape (B,))."""
        return state.values[:, self.s_off[:-1] + DISSIPATED].sum(axis=1)

    def element_energies(self, state: CouplingState) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Per element of the file: (stored J, dissipated J), each (B,)."""
        out = {}
        for i, el in enumerate(self.elements):
            idx = self.s_off[:-1][self.kernel_owner == i]
            out[el.label(i)] = (state.values[:, idx + STORED].sum(axis=1), state.values[:, idx + DISSIPATED].sum(axis=1))
        return out

    # ------------------------------------------------------------- bounds for callers
    def max_tangent_stiffness(self, angle_rad: float = 0.0, *, step_s: float | None = None) -> float:
        """An upper bound of the instantaneous tangent stiffness (N*m/rad) up to |angle_rad|.

        Sum of every spring that can act at once (Maxwell springs and slider springs included;
        each kernel kind's bound in :mod:`.kinds`); a dashpot adds none here (callers treat
        viscous terms separately, :meth:`max_damping`). ``step_s``: the shortest time step the
        caller takes (elements whose stiffness grows with the frequency they read need it).
        Used by explicit simulations (the rig) to choose or check their time step.
        """
        motion = Motion(angle_rad=abs(float(angle_rad)), step_s=step_s)
        return float(sum(kind_of(k.code).stiffness(k.params, motion) for k in self.kernels))

    def max_damping(self, *, min_frequency_hz: float = 0.0, step_s: float | None = None) -> float:
        """An upper bound of the instantaneous viscous coefficient (N*m*s/rad): dashpots in
        parallel, the series dashpots of the Pfeffer element, and the loss of the payne element
        (K''/w: ``min_frequency_hz`` is the slowest oscillation the caller drives; the kernel's
        floor of 0.01 Hz by default)."""
        motion = Motion(step_s=step_s, min_omega_rad_per_s=max(2 * np.pi * min_frequency_hz, K.MIN_OMEGA))
        return float(sum(kind_of(k.code).damping(k.params, motion) for k in self.kernels))

    def __repr__(self) -> str:
        kinds = ", ".join(e.kind for e in self.elements)
        return f"Coupling({self.name!r}: {kinds}; {self.n_sets} parameter set(s))"


def _check_dt(dt_s: float) -> None:
    if not (np.isfinite(dt_s) and dt_s > 0):
        raise DroptowerError(f"time step must be positive and finite, got {dt_s}")
