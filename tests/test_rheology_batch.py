"""The batch and stepping interface: stacked parameter sets, trial/commit, step vs simulate, and
the TOML round trip."""
from __future__ import annotations

import tomllib

import numpy as np
import pytest

from droptower.rheology import Coupling, coupling_to_toml, load_coupling, parse_coupling
from test_rheology_support import preset_paths, preset_scale, random_smooth

#: every element kind once, with internal state (Maxwell, sliders, rate-dependent sliders,
#: Pfeffer z, variable Maxwell): the structure shared by the stacked parameter sets
BASE = {"element": [
    {"kind": "spring", "stiffness": 5000.0},
    {"kind": "cubic_spring", "a": 1e5, "b": 100.0},
    {"kind": "maxwell", "stiffness": 2000.0, "damping": 4.0},
    {"kind": "elastoslide", "phi0": 0.02, "k": 8000.0, "k0": 100.0, "v_r": 2.0, "p": 7, "n": 16},
    {"kind": "masing", "n": 5, "stiffness": 300.0, "max_yield_torque": 3.0, "alpha": 2.0,
     "constriction": {"p": 200.0, "k": 0.2}},
    {"kind": "variable_maxwell", "stiffness": 1000.0, "stiffness_gain": 1e4, "damping": 3.0},
    {"kind": "pfeffer", "k1": 500.0, "alpha": 0.4, "beta": 0.1, "gamma": 0.005},
    {"kind": "dashpot", "damping": 0.5},
]}


def _variant(scale: float) -> Coupling:
    """BASE with every positive parameter scaled (same structure, other values)."""
    def scaled(el):
        out = {}
        for key, v in el.items():
            if isinstance(v, dict):
                out[key] = scaled(v)
            elif isinstance(v, float) and key not in ("alpha", "beta", "k"):
                out[key] = v * scale
            else:
                out[key] = v
        return out
    return parse_coupling({"element": [scaled(el) for el in BASE["element"]]})


def _histories(batch: int, n: int = 3000, dt: float = 1 / 38400) -> np.ndarray:
    t = np.arange(1, n + 1) * dt
    return np.array([0.03 * random_smooth(np.random.default_rng(b), t, 30.0 + 10 * b) for b in range(batch)])


def test_stack_equals_each_coupling_alone():
    parts = [_variant(s) for s in (1.0, 0.5, 2.0)]
    stacked = Coupling.stack(parts)
    assert stacked.n_sets == 3
    x = _histories(3)
    together = stacked.simulate(x, 1 / 38400)
    for b, part in enumerate(parts):
        alone = part.simulate(x[b], 1 / 38400)
        assert np.allclose(together.torque_nm[b], alone.torque_nm, rtol=1e-12, atol=1e-12)
        assert np.allclose(together.dissipated_energy_j[b], alone.dissipated_energy_j, rtol=1e-12, atol=1e-15)
    # the parameter sets really differ
    assert not np.allclose(together.torque_nm[0], together.torque_nm[1])


def test_stack_refuses_other_structures():
    from droptower.errors import DroptowerError
    with pytest.raises(DroptowerError):
        Coupling.stack([_variant(1.0), parse_coupling({"element": [{"kind": "spring", "stiffness": 1.0}]})])


def test_shared_parameters_drive_a_batch():
    """One parameter set and a (B, N) history: every row as if alone."""
    coupling = _variant(1.0)
    x = _histories(4)
    together = coupling.simulate(x, 1 / 38400).torque_nm
    for b in range(4):
        assert np.allclose(together[b], coupling.respond(x[b], 1 / 38400), rtol=1e-12, atol=1e-12)


def test_step_per_sample_equals_simulate():
    stacked = Coupling.stack([_variant(s) for s in (1.0, 0.7)])
    x = _histories(2, n=800)
    dt = 1 / 38400
    reference = stacked.simulate(x, dt)
    state = stacked.new_state(2)
    torques = np.array([stacked.step(state, x[:, n], dt) for n in range(x.shape[1])]).T
    assert np.allclose(torques, reference.torque_nm, rtol=1e-12, atol=1e-12)
    assert np.allclose(stacked.stored_energy(state), reference.stored_energy_j[:, -1], rtol=1e-12)
    assert np.allclose(stacked.dissipated_energy(state), reference.dissipated_energy_j[:, -1], rtol=1e-12)
    assert np.array_equal(state.values, reference.state.values)
    per_element = stacked.element_energies(state)
    assert len(per_element) == len(BASE["element"])
    assert np.allclose(sum(v[0] for v in per_element.values()), reference.stored_energy_j[:, -1], rtol=1e-12)


def test_every_way_of_stepping_reaches_one_compiled_step():
    """A scalar angle (on one instance a read-only broadcast view), a read-only array, a plain
    array, a trial, a batch and a history reach the history kernel with one argument type: numba
    compiles the kernel (every element kind inlined, seconds) once per process, not once per caller."""
    from droptower.rheology import kernels as K

    coupling, dt = _variant(1.0), 1 / 38400
    state = coupling.new_state(1)
    readonly = np.array([0.001])
    readonly.flags.writeable = False
    for angle in (0.001, np.float64(0.002), readonly, np.array([0.003])):
        coupling.step(state, angle, dt)
    coupling.trial(state, 0.004, dt)
    stacked = Coupling.stack([_variant(s) for s in (1.0, 0.7)])
    stacked.step(stacked.new_state(2), 0.001, dt)
    coupling.simulate(np.array([0.001, 0.002]), dt)  # a history: the same build
    assert len(K.run_history.signatures) == 1, K.run_history.signatures


def test_simulate_continues_from_a_state():
    """simulate(first half) then simulate(second half, state) equals simulate(all)."""
    coupling = _variant(1.0)
    x = _histories(1, n=1000)[0]
    whole = coupling.simulate(x, 1 / 38400).torque_nm
    first = coupling.simulate(x[:400], 1 / 38400)
    second = coupling.simulate(x[400:], 1 / 38400, state=first.state)
    assert np.allclose(np.r_[first.torque_nm, second.torque_nm], whole, rtol=1e-12, atol=1e-12)


def test_rows_taken_advanced_apart_and_merged_equal_the_whole_batch():
    """CouplingState.take / merge: rows advanced on their own and put back are the rows the whole
    batch reaches (instances are independent), bit for bit; a taken part is a copy."""
    coupling, dt = _variant(1.0), 1 / 38400
    x = _histories(5, n=600)
    first = coupling.simulate(x[:, :300], dt)
    whole = coupling.simulate(x[:, 300:], dt, state=first.state.copy())
    rows = np.array([3, 0, 4])
    part = first.state.take(rows)
    before = first.state.copy()
    coupling.simulate(x[rows, 300:], dt, state=part)
    assert np.array_equal(first.state.values, before.values)  # advancing the part left the batch alone
    first.state.merge(rows, part)
    assert np.array_equal(first.state.values[rows], whole.state.values[rows])
    assert np.array_equal(first.state.torque_nm[rows], whole.state.torque_nm[rows])
    rest = np.array([1, 2])
    assert np.array_equal(first.state.values[rest], before.values[rest])  # other rows untouched
    assert not np.array_equal(first.state.values[rows], before.values[rows])
    mask = np.array([True, False, False, True, False])
    assert np.array_equal(first.state.take(mask).angle_rad, first.state.angle_rad[[0, 3]])


def test_trial_does_not_commit():
    coupling = _variant(1.0)
    x = _histories(1, n=300)[0]
    dt = 1 / 38400
    state = coupling.new_state(1)
    for v in x[:200]:
        coupling.step(state, v, dt)
    before = (state.values.copy(), state.angle_rad.copy(), state.torque_nm.copy())

    trial_1 = coupling.trial(state, x[200] + 0.01, dt)     # a trial that will be dropped
    assert np.array_equal(state.values, before[0]) and np.array_equal(state.angle_rad, before[1])
    state.revert()
    trial_2 = coupling.trial(state, x[200], dt)            # the one that will be kept
    assert np.array_equal(state.values, before[0]) and np.array_equal(state.torque_nm, before[2])
    assert not np.allclose(trial_1, trial_2)
    state.commit()
    assert not np.array_equal(state.values, before[0])
    assert state.angle_rad[0] == x[200] and state.torque_nm[0] == trial_2[0]

    # committed trial == a plain step from the same state
    reference = coupling.new_state(1)
    for v in x[:201]:
        coupling.step(reference, v, dt)
    assert np.array_equal(state.values, reference.values)
    with pytest.raises(RuntimeError):
        state.commit()                                     # nothing left to commit


@pytest.mark.parametrize("path", preset_paths(), ids=lambda p: p.stem)
def test_toml_round_trip(path, tmp_path):
    """coupling_to_toml writes a file that loads to the same parameters and torques."""
    coupling = load_coupling(path)
    text = coupling_to_toml(coupling)
    again_path = tmp_path / path.name
    again_path.write_text(text)
    again = load_coupling(again_path)
    assert np.array_equal(again.params, coupling.params)
    assert np.array_equal(again.codes, coupling.codes)
    assert (again.name, again.units, again.source) == (coupling.name, coupling.units, coupling.source)
    amplitude, frequency = preset_scale(coupling)
    t = np.arange(1, 2001) / 38400
    x = amplitude * np.sin(2 * np.pi * frequency * t)
    assert np.array_equal(again.respond(x, t[0]), coupling.respond(x, t[0]))
    assert tomllib.loads(text)["element"]
