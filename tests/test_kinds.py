"""Every element kind through every consumer of the kernel records (droptower.rheology.kinds).

Each element kind a coupling file may use gets random parameter sets here; each is compiled
(elements), checked against its kernel kinds' layouts, stepped (kernels) through random
histories, its energies and bounds (coupling) checked against the torque it produced, its lever
free decay (identify.lever) checked against a plain loop of Coupling.step, and its batches
against single runs. A kind missing from any of these fails here.
"""
from __future__ import annotations

import numpy as np
import pytest

import droptower as dt
from droptower.identify.lever import free_decay
from droptower.rheology import Coupling, kinds
from droptower.rheology import kernels as K
from droptower.rheology.elements import ELEMENT_KINDS, ElementUnion, KernelElement
from droptower.rig.lever_decay import SYMPLECTIC_EULER, VERLET, LeverDecay
from pydantic import TypeAdapter

SPEC = TypeAdapter(ElementUnion)


def _curve(rng, n, slope):
    """A rising piecewise-linear curve through (0, 0): knots (rad) and values."""
    x = np.sort(np.concatenate([[0.0], rng.uniform(-0.05, 0.05, n - 1)]))
    y = np.cumsum(np.concatenate([[0.0], slope * rng.uniform(0.3, 3.0, n - 1) * np.diff(x)]))
    return list(x), list(y - np.interp(0.0, x, y))


def _table(rng, n, lo, hi, start=None):
    x = np.sort(rng.uniform(lo, hi, n))
    if start is not None:
        x[0] = start
    return x, np.sort(rng.uniform(1.0, 3.0, n))


def _variable_maxwell(rng):
    k = float(rng.uniform(1e3, 5e3))
    choice = rng.integers(3)
    spec = {"kind": "variable_maxwell"}
    if choice == 0:
        spec |= {"stiffness": k, "stiffness_gain": float(rng.uniform(0, 1e5))}
    elif choice == 1:
        x, y = _table(rng, 5, 0.0, 0.05, start=0.0)  # k rising with e >= 0, the first value below
        spec |= {"stiffness_table": {"x": list(x), "y": list(k * y)}}
    else:
        x, y = _curve(rng, 6, k)
        spec |= {"force_table": {"x": x, "y": y}}
    if rng.integers(2):
        spec |= {"damping": float(rng.uniform(1, 50))}
    else:
        v, c = _table(rng, 5, 0.0, 5.0, start=0.0)
        spec |= {"damping_table": {"x": list(v), "y": list(20 * c)}}  # c rising: c(v) v rises
    return spec


# one factory per element kind a coupling file may use: random parameters, SI units
FACTORIES = {
    "spring": lambda r: {"stiffness": r.uniform(1e3, 1e4)},
    "spring_table": lambda r: dict(zip(("angle", "torque"), _curve(r, 7, 5e3))),
    "cubic_spring": lambda r: {"a": r.uniform(0, 1e7), "b": r.uniform(1e3, 1e4)},
    "dashpot": lambda r: {"damping": r.uniform(1, 50)},
    "maxwell": lambda r: {"stiffness": r.uniform(1e3, 1e4), "damping": r.uniform(1, 50)},
    "prony": lambda r: {"equilibrium_stiffness": r.uniform(1e3, 1e4),
                        "terms": [{"stiffness": r.uniform(1e2, 1e4), "relaxation_time": r.uniform(1e-3, 1)}
                                  for _ in range(3)]},
    "prandtl": lambda r: {"stiffness": r.uniform(1e3, 1e4), "yield_torque": r.uniform(5, 50)},
    "masing": lambda r: {"n": 5, "stiffness": r.uniform(1e3, 1e4), "max_yield_torque": r.uniform(5, 50),
                         "alpha": r.uniform(0, 3), "constriction": {"p": r.uniform(10, 300), "k": r.uniform(0, 1)}},
    "elastoslide": lambda r: {"phi0": r.uniform(0.02, 0.2), "k": r.uniform(1e3, 1e4), "k0": r.uniform(0, 1e3),
                              "v_r": r.uniform(0.01, 1), "p": int(r.choice([1, 3, 7])), "n": 8},
    "mullins": lambda r: {"tau": r.uniform(1e-3, 1), "slow_curve": {"kind": "spring_table",
                          **dict(zip(("angle", "torque"), _curve(r, 5, 2e3)))}, "fast_stiffness": r.uniform(1e4, 2e4)},
    "variable_maxwell": _variable_maxwell,
    "pfeffer": lambda r: {"k1": r.uniform(1e3, 1e4), "alpha": r.uniform(0.1, 2), "beta": r.uniform(0, 2),
                          "gamma": r.uniform(1e-4, 1e-2),
                          "friction": {"max_torque": r.uniform(5, 50), "min_yield_angle": 1e-4, "max_yield_angle": 1e-2}},
    "payne": lambda r: {"stiffness": r.uniform(1e3, 2e4), "critical_angle": r.uniform(1e-3, 2e-2),
                        "exponent": r.uniform(0.4, 0.8), "loss_stiffness": r.uniform(0, 500),
                        "loss_peak_stiffness": r.uniform(0, 3e3), "storage_frequency_exponent": r.choice([0.0, 0.1]),
                        "loss_frequency_exponent": r.choice([0.0, 0.1]), "memory_time": 0.5},
    "filler_network": lambda r: {"stiffness": r.uniform(1e3, 2e4), "critical_angle": r.uniform(1e-3, 2e-2),
                                 "exponent": r.uniform(0.4, 0.8), "breakdown_angle": r.uniform(1e-3, 5e-2),
                                 "recovery_time": r.uniform(0.01, 1.0), "centre_relaxation_time": r.uniform(0.01, 1.0),
                                 "n": 8},
    "large_strain_network": lambda r: {"stiffness": r.uniform(1e3, 1e4), "gain": r.uniform(0, 1e6),
                                       "exponent": r.uniform(1, 4), "network_stiffness": r.uniform(1e3, 2e4),
                                       "slip": r.uniform(2e-3, 2e-2), "spread": r.uniform(0.5, 3),
                                       "friction_gain": r.uniform(0, 1e3), "damage": r.uniform(0, 0.9),
                                       "damage_angle": r.uniform(5e-3, 5e-2), "damage_exponent": r.uniform(0.5, 2),
                                       "damage_travel": r.uniform(5e-3, 5e-2), "n": 8},
    "power_law": lambda r: {"storage_stiffness": r.uniform(1e3, 5e3), "loss_factor": r.uniform(0.1, 1),
                            "reference_frequency": 100.0, "min_frequency": 10.0, "max_frequency": 1e3},
}
SEEDS = range(3)
#: Element kinds with a nonlinear spring: the trapezoidal work of a step matches the change of
#: stored energy to O(h^3) only (the others book it exactly, to round-off).
NONLINEAR_SPRINGS = {"spring_table", "cubic_spring", "mullins", "variable_maxwell"}
CASES = [(kind, seed) for kind in sorted(FACTORIES) for seed in SEEDS]


def _element(kind: str, seed: int):
    rng = np.random.default_rng([seed, sorted(FACTORIES).index(kind)])
    values = {k: (float(v) if isinstance(v, np.floating) else v) for k, v in FACTORIES[kind](rng).items()}
    return SPEC.validate_python({"kind": kind, **values})


def _history(seed: int, n: int = 600, h: float = 2e-4) -> np.ndarray:
    """A random angle history (rad): three sines of random amplitudes, frequencies and phases on a ramp."""
    rng = np.random.default_rng(1000 + seed)
    t = np.arange(1, n + 1) * h
    x = sum(rng.uniform(0.002, 0.02) * np.sin(2 * np.pi * rng.uniform(5, 200) * t + rng.uniform(0, 6))
            for _ in range(3)) + rng.uniform(-0.2, 0.2) * t
    return x - x[0] * np.exp(-t / 4e-3)  # starts near 0 (the virgin state's angle)


def test_every_kind_has_a_factory_and_every_record_is_reached():
    assert set(FACTORIES) == set(ELEMENT_KINDS)
    reached = {kern.code for kind, seed in CASES for kern in Coupling([_element(kind, seed)]).kernels}
    assert reached == set(kinds.KINDS)
    for record in kinds.KINDS.values():
        assert getattr(K, record.name.upper()) == record.code and record.step is getattr(K, record.name)


def test_a_layout_that_disagrees_with_its_record_is_refused():
    with pytest.raises(ValueError, match=r"maxwell kernel element has 3 parameters; its layout \(k, c\) needs 2"):
        KernelElement(K.MAXWELL, np.array([1.0, 2.0, 3.0]))
    with pytest.raises(ValueError, match="slider_bank kernel element has 13 parameters.* needs 17"):
        KernelElement(K.SLIDER_BANK, np.array([3.0, 0, 0, 0, 0, *np.ones(8)]))
    assert KernelElement(K.SLIDER_BANK, np.array([2.0, 0, 0, 0, 0, *np.ones(8)])).n_internal == 6
    with pytest.raises(ValueError, match="maxwell kernel element has 5 internal variables, not 3"):
        KernelElement(K.MAXWELL, np.array([1.0, 2.0]), 3)
    with pytest.raises(KeyError, match="kernel code 99 has no record"):
        KernelElement(99, np.array([1.0]))


@pytest.mark.parametrize("kind,seed", CASES)
def test_kind_through_every_consumer(kind, seed):
    h = 2e-4
    coupling = Coupling([_element(kind, seed)])
    x = _history(seed, h=h)
    # kernels: finite torque and the energy books: stored + dissipated = the trapezoidal work,
    # exactly, or for a nonlinear spring converging with the step (second order for a smooth
    # curve; a table's knot crossings make it irregular: a quarter of the step gains at least 4x)
    response, error = _books(coupling, x, h)
    assert np.all(np.isfinite(response.torque_nm))
    if kind in NONLINEAR_SPRINGS:
        assert error < 1e-2 and _books(coupling, _history(seed, n=4 * x.size, h=h / 4), h / 4)[1] <= error / 4
    else:
        assert error <= 1e-12
    scale = np.max(np.abs(response.torque_nm)) * np.max(np.abs(x))
    assert np.all(response.stored_energy_j >= -1e-12 * scale) and response.dissipated_energy_j[-1] >= -1e-9 * scale

    # bounds: the finite-difference tangent of one step from random points of the history
    rng = np.random.default_rng(seed)
    motion_angle = 2.0 * np.max(np.abs(x))
    stiffness = coupling.max_tangent_stiffness(motion_angle, step_s=h)
    damping = coupling.max_damping(step_s=h)
    state, done = coupling.new_state(1), 0
    for stop in np.sort(rng.choice(np.arange(10, x.size - 1), 6, replace=False)):
        coupling.simulate(x[done:stop], h, state)
        done = stop
        delta = 1e-7 * max(abs(x[stop] - x[stop - 1]), 1e-4)
        t0 = coupling.trial(state, x[stop], h)[0]
        t1 = coupling.trial(state, x[stop] + delta, h)[0]
        tangent = (t1 - t0) / delta
        assert tangent <= (stiffness + damping / h) * (1 + 1e-6) + 1e-6, (stop, tangent, stiffness, damping)

    # lever: the compiled free decay (identification: Verlet; plan: symplectic Euler, from a
    # preloaded rest) equals its scheme written out over Coupling.step, row by row
    lever = Coupling([_element("spring", seed), _element(kind, seed)])
    inertia, rate0, n = np.array([0.2, 0.35]), np.array([3.0, -2.0]), 300
    angle, lever_torque = free_decay(lever, inertia, rate0, n, h)
    ref_angle, ref_torque = _verlet(lever, inertia, rate0, n, h)
    assert np.allclose(angle, ref_angle, rtol=0, atol=1e-12 * np.max(np.abs(ref_angle)))
    assert np.allclose(lever_torque, ref_torque, rtol=0, atol=1e-9 * np.max(np.abs(ref_torque)))
    rest = lever.new_state(2)
    lever.simulate(np.linspace(0.0, 0.01, 50)[None, :].repeat(2, axis=0), h, rest)
    euler_angle, euler_torque = LeverDecay(lever, rest.copy(), inertia, rate0, h, SYMPLECTIC_EULER).advance(n)
    ref_angle, ref_torque = _symplectic_euler(lever, rest.copy(), inertia, rate0, n, h)
    assert np.array_equal(euler_angle, ref_angle) and np.array_equal(euler_torque, ref_torque)

    # batching: stacked parameter sets (one call, and chunks of rows on threads) equal single runs
    others = [Coupling([_element(kind, s)]) for s in (seed, seed + 10)]
    if not all(np.array_equal(o.p_off, others[0].p_off) for o in others):
        others = others[:1]
    stacked = Coupling.stack(others * 4)  # batch of >= 4 rows; 8 rows run on threads
    rows = np.stack([_history(seed + i, h=h) for i in range(stacked.n_sets)])
    batch = stacked.simulate(rows, h).torque_nm
    for i, single in enumerate(others * 4):
        assert np.array_equal(batch[i], single.respond(rows[i], h))


def _books(coupling: Coupling, x: np.ndarray, h: float):
    """The response to ``x`` and the largest mismatch of stored + dissipated energy against the
    trapezoidal work, relative to peak torque times peak angle."""
    response = coupling.simulate(x, h)
    torque = response.torque_nm
    work = np.cumsum(0.5 * (np.concatenate([[0.0], torque[:-1]]) + torque) * np.diff(np.concatenate([[0.0], x])))
    books = response.stored_energy_j + response.dissipated_energy_j
    return response, float(np.max(np.abs(work - books)) / (np.max(np.abs(torque)) * np.max(np.abs(x))))


def _verlet(coupling: Coupling, inertia, rate0, n, h):
    """The lever's free decay by velocity Verlet over Coupling.step (the reference of identify.lever)."""
    state = coupling.new_state(inertia.size)
    angle, torque = np.zeros((inertia.size, n + 1)), np.zeros((inertia.size, n + 1))
    phi, v, acc = np.zeros(inertia.size), rate0.copy(), np.zeros(inertia.size)
    for k in range(1, n + 1):
        phi = phi + h * v + 0.5 * h * h * acc
        t = coupling.step(state, phi, h)
        acc_new = -t / inertia
        v = v + 0.5 * h * (acc + acc_new)
        acc = acc_new
        angle[:, k], torque[:, k] = phi, t
    return angle, torque


def _symplectic_euler(coupling: Coupling, state, inertia, rate0, n, h):
    """The rig's scheme over Coupling.step from a rest held by the screw (the plan's reference)."""
    screw, x_rest = state.torque_nm.copy(), state.angle_rad.copy()
    angle, torque = np.zeros((inertia.size, n)), np.zeros((inertia.size, n))
    phi, v = np.zeros(inertia.size), rate0.copy()
    for k in range(n):
        phi = phi + h * v
        t = coupling.step(state, x_rest + phi, h)
        v = v + (screw - t) / inertia * h
        angle[:, k], torque[:, k] = phi, t
    return angle, torque


def test_lever_batches_equal_single_rows():
    """A batch large enough to run on threads decays row by row as each row alone."""
    coupling = Coupling.stack([Coupling([_element("spring", s), _element("payne", s)]) for s in range(8)])
    inertia, rate0 = np.linspace(0.15, 0.5, 8), np.linspace(-3.0, 3.0, 8)
    for scheme in (SYMPLECTIC_EULER, VERLET):
        batch = LeverDecay(coupling, coupling.new_state(), inertia, rate0, 2e-4, scheme).advance(400)
        for i in range(8):
            row = Coupling(coupling.elements, params=coupling.params[i:i + 1])
            single = LeverDecay(row, row.new_state(), inertia[i:i + 1], rate0[i:i + 1], 2e-4, scheme).advance(400)
            assert np.array_equal(batch[0][i], single[0][0]) and np.array_equal(batch[1][i], single[1][0])


def test_stiffness_bound_of_the_reference_coupling_covers_its_tangent():
    """The default rapp2022_nr60 coupling: the bound must hold the first step's tangent from rest
    (every spring acts at once), where the payne element adds its full stiffness."""
    coupling = dt.load_coupling("rapp2022_nr60")
    h = 1e-5
    state = coupling.new_state(1)
    delta = 1e-7
    tangent = (coupling.trial(state, 2 * delta, h)[0] - coupling.trial(state, delta, h)[0]) / delta
    bound = coupling.max_tangent_stiffness(0.0, step_s=h)
    assert tangent <= bound <= 1.05 * tangent, (tangent, bound)


def test_damping_bound_of_the_payne_element_covers_its_loss():
    """After some cycles at 20 Hz the payne element's dashpot is K''/w; the bound for motions no
    slower than 20 Hz must cover it (the step's tangent minus the springs)."""
    spec = SPEC.validate_python({"kind": "payne", "stiffness": 1e4, "critical_angle": 5e-3, "loss_stiffness": 100.0,
                                 "loss_peak_stiffness": 2e3})
    coupling = Coupling([spec])
    h, f = 1e-4, 20.0
    t = np.arange(1, 2001) * h
    state = coupling.new_state(1)
    coupling.simulate(5e-3 * np.sin(2 * np.pi * f * t), h, state)
    x = state.angle_rad[0]
    delta = 1e-9
    tangent = (coupling.trial(state, x + 2e-6 + delta, h)[0] - coupling.trial(state, x + 2e-6, h)[0]) / delta
    damping = coupling.max_damping(min_frequency_hz=0.9 * f)
    assert (tangent - coupling.max_tangent_stiffness(step_s=h)) * h <= damping
    assert damping <= (100.0 + 2e3) / (2 * np.pi * 0.9 * f) * (1 + 1e-12)
    assert coupling.max_damping() >= damping  # the kernel's floor (0.01 Hz) is slower still

