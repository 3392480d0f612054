"""One record per kernel kind: code, parameter and state layout, step function, bounds.

A coupling compiles into kernel elements (:mod:`.elements`); each is one of the kinds below. The
record of a kind is what every consumer reads instead of knowing the layout itself:

- :mod:`.elements` writes the flat parameter vector and declares the internal state; a
  :class:`~droptower.rheology.elements.KernelElement` is checked against its kind's layout;
- :mod:`.kernels` steps it (``step`` is the numba kernel, dispatched by ``code`` in
  :func:`~droptower.rheology.kernels.step_element`);
- :class:`~droptower.rheology.coupling.Coupling` sums the kinds' stiffness and damping bounds
  (the rig's time-step check, the preload's bracket) and reads the energies from the common
  state header;
- ``droptower.identify.lever`` steps whole couplings through :func:`.kernels.step_instance`.

Adding a kind: its kernel (and its branch of ``step_element``) in :mod:`.kernels`, one record
here, the element spec that compiles to it in :mod:`.elements`; then ``python -m
droptower.rheology.slots`` writes the record's named slot offsets (``P_<KIND>_<PARAM>``,
``S_<KIND>_<STATE>``) into the kernels, which index by them (:mod:`.slots`). ``tests/test_kinds.py`` walks
every kind through every consumer, so a kind registered in only some of them fails there.

Every kernel's state starts with the same header (:data:`HEADER`): stored energy (J), energy
dissipated since the state was created (J), torque at the end of the step (N*m); the internal
variables follow.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from droptower.rheology import kernels as K

HEADER = ("stored_energy_j", "dissipated_energy_j", "torque_nm")
STORED, DISSIPATED, TORQUE = range(len(HEADER))  # the kernels' S_* header slots (droptower.rheology.slots)


@dataclass(frozen=True)
class Motion:
    """What a caller knows of the motions it drives, for the bounds: the largest excursion of the
    angle (rad), the shortest time step (s, None: any) and the slowest oscillation (rad/s, at least
    the payne kernel's floor)."""

    angle_rad: float = 0.0
    step_s: float | None = None
    min_omega_rad_per_s: float = K.MIN_OMEGA


def _none(named: dict[str, float], params: np.ndarray, motion: Motion) -> float:
    return 0.0


@dataclass(frozen=True)
class KernelKind:
    """The record of one kernel kind.

    params: names of the fixed parameter slots at the start of the element's parameter slice
    (variable-length tables follow them, sized by ``n_params``); internal: names of the internal
    state slots after :data:`HEADER` (repeated blocks sized by ``n_internal``).
    stiffness_bound(named, params, motion): an upper bound of the tangent stiffness (N*m/rad) in
    the :class:`Motion`, viscous terms left out; damping_bound(named, params, motion): an upper
    bound of the viscous coefficient (N*m*s/rad); ``named`` maps the slot names to their values,
    ``params`` is the whole slice (for the tables). Over one step of ``h`` seconds the tangent
    dT/dx1 is at most stiffness + damping / h (:meth:`stiffness`, :meth:`damping`).
    """

    name: str
    code: int
    step: Callable
    params: tuple[str, ...]
    internal: tuple[str, ...]
    stiffness_bound: Callable[[dict[str, float], np.ndarray, Motion], float]
    damping_bound: Callable[[dict[str, float], np.ndarray, Motion], float] = _none
    n_params: Callable[[dict[str, float]], int] | None = None    # of the named slots; None: len(params)
    n_internal: Callable[[dict[str, float]], int] | None = None  # of the named slots; None: len(internal)

    def param_slot(self, name: str) -> int:
        """Index of a named parameter in the element's parameter slice."""
        return self.params.index(name)

    def named(self, params: np.ndarray) -> dict[str, float]:
        """The named parameter slots of an element's parameter slice."""
        return dict(zip(self.params, map(float, params[:len(self.params)])))

    def pack(self, **values: float) -> np.ndarray:
        """The parameter vector of a kind without tables, from its slots by name (all required)."""
        if set(values) != set(self.params):
            raise TypeError(f"{self.name} parameters are {', '.join(self.params)}; got {', '.join(values)}")
        return np.array([values[name] for name in self.params], dtype=float)

    def stiffness(self, params: np.ndarray, motion: Motion) -> float:
        """Upper bound of an element's tangent stiffness (N*m/rad), viscous terms left out."""
        return float(self.stiffness_bound(self.named(params), params, motion))

    def damping(self, params: np.ndarray, motion: Motion) -> float:
        """Upper bound of an element's viscous coefficient (N*m*s/rad)."""
        return float(self.damping_bound(self.named(params), params, motion))

    def state_slot(self, name: str) -> int:
        """Index of a named state variable (header or internal) in the element's state slice."""
        return (HEADER + self.internal).index(name)

    def params_size(self, params: np.ndarray) -> int:
        """Length of an element's parameter slice (its named slots and tables)."""
        return len(self.params) if self.n_params is None else self.n_params(self.named(params))

    def internal_size(self, params: np.ndarray) -> int:
        """Number of an element's internal state variables."""
        return len(self.internal) if self.n_internal is None else self.n_internal(self.named(params))

    def check(self, params: np.ndarray) -> None:
        """Raise ValueError if a compiled parameter vector does not have this kind's layout."""
        need = self.params_size(params) if params.ndim == 1 and params.size >= len(self.params) else len(self.params)
        if params.ndim != 1 or params.size != need:
            tables = ", tables" if self.n_params else ""
            raise ValueError(f"a {self.name} kernel element has {params.size} parameters; its layout "
                             f"({', '.join(self.params)}{tables}) needs {need}")


# ---------------------------------------------------------------- bounds of the kinds
def _table_slopes(xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
    return np.diff(ys) / np.diff(xs)


def _table_spring_stiffness(v, p, motion):
    n = int(v["n"])
    return float(np.max(_table_slopes(p[1:1 + n], p[1 + n:1 + 2 * n])))


def _slider_bank_stiffness(v, p, motion):
    # the springs act in series with sliders (a slipping one adds no stiffness); the constriction
    # S(x) = (|tanh(P x)| + K)/(1 + K) <= 1 adds S'(x) times the bank force, and a Coulomb bank's
    # force is at most the sum of its limits (Heine & Plagemann 2014). A rate-dependent bank carries no constriction.
    n = int(v["n"])
    springs, limits = p[5:5 + n], p[5 + n:5 + 2 * n]
    p_c, k_c = v["constriction_p"], v["constriction_k"]
    return float(np.sum(springs)) + (p_c / (1.0 + k_c) * float(np.sum(limits)) if p_c > 0 else 0.0)


def _variable_maxwell_stiffness(v, p, motion):
    # the spring in series with the dashpot bounds the branch's tangent over any step
    nk = int(v["nk"])
    tables = K.P_VARIABLE_MAXWELL_TABLES
    xs, ys = p[tables:tables + nk], p[tables + nk:tables + 2 * nk]
    if nk and v["force_mode"] > 0:  # force table: its steepest segment
        return float(np.max(_table_slopes(xs, ys)))
    if nk:  # stiffness table: d(k(e) e)/de = k + k' e, linear in e on a segment, extreme at its knots
        slopes = _table_slopes(xs, ys)
        left = np.concatenate([[0.0], slopes])   # k' on the segment left of each knot (0 beyond the table)
        right = np.concatenate([slopes, [0.0]])
        return float(np.max(np.maximum(ys + left * xs, ys + right * xs)))
    # (k0 + g|e|) e: the branch elongation is at most the largest change of angle, twice the excursion
    return v["k0"] + 4.0 * v["gain"] * motion.angle_rad


def _pfeffer_stiffness(v, p, motion):
    return v["k1"] * (1.0 + v["alpha"])  # k1 (1 + alpha): both springs, the series dashpot c1 locked


def _pfeffer_damping(v, p, motion):
    return v["gamma"] * v["k1"]  # c1 = gamma k1 (c2 acts in series with it)


def _payne_frequency_ratio_cap(v, motion):
    """Largest w / w_ref the payne kernel can read: a half cycle lasts at least
    MIN_HALF_CYCLE_STEPS steps, so w <= pi / (MIN_HALF_CYCLE_STEPS h); any w without a step."""
    if motion.step_s is None:
        return np.inf
    return max(1.0, np.pi / (K.MIN_HALF_CYCLE_STEPS * motion.step_s) / v["reference_omega"])


def _payne_stiffness(v, p, motion):
    # k <= dK (w/w_ref)^beta_s: Kraus's storage shape is at most 1, and the centre's relaxation
    # only lowers the elongation's tangent de1/dx1 = tau (1 - exp(-h/tau)) / h <= 1
    beta_s = v["storage_frequency_exponent"]
    return v["stiffness"] * (_payne_frequency_ratio_cap(v, motion) ** beta_s if beta_s > 0 else 1.0)


def _payne_damping(v, p, motion):
    # c = K''(A) (w/w_ref)^beta_l / w with K'' <= loss_0 + loss_peak (Kraus's loss shape peaks at
    # 1) and w no slower than the motion, nor than the kernel's floor MIN_OMEGA
    omega = max(motion.min_omega_rad_per_s, K.MIN_OMEGA)
    beta_l = v["loss_frequency_exponent"]
    growth = _payne_frequency_ratio_cap(v, motion) ** beta_l if beta_l > 0 else 1.0
    return (v["loss_stiffness"] + v["loss_peak_stiffness"]) * growth / omega


# ---------------------------------------------------------------- the records
LINEAR_SPRING = KernelKind(
    "linear_spring", K.LINEAR_SPRING, K.linear_spring, params=("k",), internal=(),
    stiffness_bound=lambda v, p, motion: v["k"])
TABLE_SPRING = KernelKind(
    "table_spring", K.TABLE_SPRING, K.table_spring, params=("n",), internal=(),
    stiffness_bound=_table_spring_stiffness,
    n_params=lambda v: 1 + 3 * int(v["n"]))  # then x_1..x_n, T_1..T_n, E_1..E_n
CUBIC_SPRING = KernelKind(
    "cubic_spring", K.CUBIC_SPRING, K.cubic_spring, params=("a", "b"), internal=(),
    stiffness_bound=lambda v, p, motion: 3.0 * v["a"] * motion.angle_rad ** 2 + v["b"])
DASHPOT = KernelKind(
    "dashpot", K.DASHPOT, K.dashpot, params=("c",), internal=(),
    stiffness_bound=_none, damping_bound=lambda v, p, motion: v["c"])
MAXWELL = KernelKind(
    "maxwell", K.MAXWELL, K.maxwell, params=("k", "c"),
    internal=("elongation_rad", "cached_hk", "cached_c", "cached_decay", "cached_gain"),
    stiffness_bound=lambda v, p, motion: v["k"])  # tangent k tau (1 - exp(-h/tau)) / h <= k
SLIDER_BANK = KernelKind(
    "slider_bank", K.SLIDER_BANK, K.slider_bank, params=("n", "v_r", "p", "constriction_p", "constriction_k"),
    internal=(),  # elongations e_1..e_n, trial elongations, Newton iterates: 3n slots
    stiffness_bound=_slider_bank_stiffness,
    n_params=lambda v: 5 + 4 * int(v["n"]), n_internal=lambda v: 3 * int(v["n"]))
VARIABLE_MAXWELL = KernelKind(
    "variable_maxwell", K.VARIABLE_MAXWELL, K.variable_maxwell,
    params=("k0", "gain", "c0", "nk", "nc", "force_mode"),
    internal=("elongation_rad", "cached_h", "cached_c_over_h"),
    stiffness_bound=_variable_maxwell_stiffness,
    # then the tables: e_1..e_nk, k or f at them, v_1..v_nc, c at them; in force mode the knot
    # energies and the segment slopes
    n_params=lambda v: len(v) + 2 * int(v["nk"]) + 2 * int(v["nc"]) + (2 * int(v["nk"]) - 1 if v["force_mode"] > 0 else 0))
PFEFFER = KernelKind(
    "pfeffer", K.PFEFFER, K.pfeffer, params=("k1", "alpha", "beta", "gamma"),
    internal=("z_rad", "cached_lambda_h", "cached_decay"),
    stiffness_bound=_pfeffer_stiffness, damping_bound=_pfeffer_damping)
PAYNE = KernelKind(
    "payne", K.PAYNE, K.payne,
    params=("stiffness", "critical_angle", "exponent", "loss_stiffness", "loss_peak_stiffness",
            "centre_relaxation_time", "memory_time", "storage_frequency_exponent", "loss_frequency_exponent",
            "reference_omega", "rest_relaxation_time"),
    internal=("elongation_rad", "stiffness", "damping", "omega", "peak_elongation", "peak_rate", "elapsed_s",
              "half_cycle_sign", "mode", "cached_centre_decay", "cached_h", "cached_rest_decay"),
    stiffness_bound=_payne_stiffness, damping_bound=_payne_damping)

MAXWELL_BANK = KernelKind(
    "maxwell_bank", K.MAXWELL_BANK, K.maxwell_bank, params=("n",),
    internal=("cached_h", "cached_k1", "cached_c1"),  # then e_1..e_n, their decays and ramp factors: 3n slots
    # each term's tangent k_i tau_i (1 - exp(-h/tau_i)) / h <= k_i
    stiffness_bound=lambda v, p, motion: float(np.sum(p[1:1 + int(v["n"])])),
    n_params=lambda v: 1 + 2 * int(v["n"]), n_internal=lambda v: 3 + 3 * int(v["n"]))
FILLER_NETWORK = KernelKind(
    "filler_network", K.FILLER_NETWORK, K.filler_network,
    params=("n", "breakdown_angle", "two_m", "recovery_time", "centre_relaxation_time", "rest_rate"),
    internal=("damage", "centre_elongation_rad", "cached_h", "cached_h_over_centre_time", "cached_centre_over_recovery_time",
              "cached_inverse_rest_step", "cached_g_cap", "cached_threshold_rad"),  # then e_1..e_n
    # every spring of the intact network sticking (g <= 1); the element has no viscous part
    stiffness_bound=lambda v, p, motion: float(np.sum(p[K.P_FILLER_NETWORK_TABLES:][:int(v["n"])])),
    n_params=lambda v: K.P_FILLER_NETWORK_TABLES + 2 * int(v["n"]),
    n_internal=lambda v: K.S_FILLER_NETWORK_BLOCKS - K.N_HEADER + int(v["n"]))



def _large_strain_network_stiffness(v: dict[str, float], p: np.ndarray, motion: Motion) -> float:
    """Upper bound of the large-strain network's tangent (N*m/rad) up to the motion's angle A: the
    intact spring's k + a (q + 1) A^q, the network's n k_n (1 + g A^2) (every spring sticking) and
    its stiffening's g k_n n (4 A s + s^2), s the largest slip (the damage only lowers it)."""
    a_max = motion.angle_rad
    slip = float(np.max(p[K.P_LARGE_STRAIN_NETWORK_TABLES:][:int(v["n"])], initial=0.0))
    network = v["n"] * v["network_stiffness"]
    return (v["stiffness"] + v["gain"] * (v["exponent"] + 1.0) * a_max ** v["exponent"]
            + network * (1.0 + v["friction_gain"] * (a_max * a_max + 4.0 * a_max * slip + slip * slip)))


LARGE_STRAIN_NETWORK = KernelKind(
    "large_strain_network", K.LARGE_STRAIN_NETWORK, K.large_strain_network,
    params=("n", "stiffness", "gain", "exponent", "network_stiffness", "friction_gain", "damage_max", "damage_angle",
            "damage_exponent", "damage_travel", "travel_softening", "travel_exponent", "slip_hardening", "damage_sides"),
    internal=("damage", "peak_angle_rad", "travel_rad", "reversal_angle_rad", "direction", "damage_negative",
              "peak_negative_angle_rad"),  # then e_1..e_n
    stiffness_bound=_large_strain_network_stiffness,
    n_params=lambda v: K.P_LARGE_STRAIN_NETWORK_TABLES + int(v["n"]),  # then the slips s_1..s_n
    n_internal=lambda v: K.S_LARGE_STRAIN_NETWORK_BLOCKS - K.N_HEADER + int(v["n"]))

KINDS: dict[int, KernelKind] = {k.code: k for k in (
    LINEAR_SPRING, TABLE_SPRING, CUBIC_SPRING, DASHPOT, MAXWELL, SLIDER_BANK, VARIABLE_MAXWELL, PFEFFER, PAYNE,
    MAXWELL_BANK, FILLER_NETWORK, LARGE_STRAIN_NETWORK)}


def kind_of(code: int) -> KernelKind:
    """The record of a kernel code (KeyError names an unregistered code)."""
    try:
        return KINDS[int(code)]
    except KeyError:
        raise KeyError(f"kernel code {code} has no record in droptower.rheology.kinds") from None
