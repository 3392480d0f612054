"""Passivity and the energy balance, as properties (hypothesis) over every element kind with
random valid parameters, every shipped preset, and random closed histories.

For any history that starts from the virgin state at angle 0 and returns to angle 0:
- the coupling dissipates >= 0 energy and stores >= 0 energy (so the work done on it is >= 0);
- stored + dissipated energy equals the work done on it, W_n = sum of 1/2 (T_k + T_k+1)
  (x_k+1 - x_k) from the first step on, computed here from the torque and angle histories only.

Tolerances. The kernels account dissipation as the mean (trapezoidal) force on each dashpot or
slider times its stroke, so for every element whose springs are linear the balance holds step
by step to round-off: 1e-9 of the total absolute work sum |dW| (plus 1e-18 J, and for static
curves their energy's round-off, see ``roundoff_floor``). For the
nonlinear springs the stored energy is the exact integral of the spring force while the work
is a trapezoidal sum, so the balance holds to the trapezoidal rule's error, O(h^2) over a
history. There the tolerance is that error's bound, computed per element from the history
(see ``nonlinear_bound``): never a fixed fraction.
"""
from __future__ import annotations

import os

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from droptower.errors import DroptowerError
from droptower.rheology import load_coupling, parse_coupling
from test_rheology_support import preset_paths, preset_scale, single, trapezoid_work

#: CI runs a fixed set of 40 examples per test (derandomised: reproducible, no database
#: files); DROPTOWER_HYPOTHESIS_EXAMPLES=1000 explores that many random ones instead.
_EXAMPLES = int(os.environ.get("DROPTOWER_HYPOTHESIS_EXAMPLES", "0"))
SETTINGS = settings(max_examples=_EXAMPLES or 40, deadline=None, derandomize=not _EXAMPLES, database=None,
                    suppress_health_check=[HealthCheck.too_slow])

stiffness = st.floats(1.0, 1e5)
log_float = lambda lo, hi: st.floats(np.log10(lo), np.log10(hi)).map(lambda v: float(10 ** v))  # noqa: E731


@st.composite
def closed_history(draw):
    """(angle (N,), dt): random piecewise-linear or smooth, from 0 back to exactly 0, with a
    peak of 1e-4 ... 0.1 rad (at far smaller scales the interpolation of tables loses the
    angle against the knots' values: absolute round-off, not a property of the model)."""
    scale = draw(log_float(1e-4, 0.1))                    # rad
    dt = draw(st.sampled_from([1 / 38400, 1 / 2048, 1 / 500, 1 / 50]))
    n = draw(st.integers(50, 1500))
    i = np.arange(1, n + 1)
    if draw(st.booleans()):
        k = draw(st.integers(1, 8))
        values = draw(st.lists(st.floats(-1.0, 1.0), min_size=k, max_size=k))
        where = np.sort(draw(st.lists(st.integers(1, n - 1), min_size=k, max_size=k, unique=True)))
        x = np.interp(i, np.r_[0, where, n], np.r_[0.0, values, 0.0])
    else:
        m = draw(st.lists(st.integers(1, 12), min_size=1, max_size=4))
        a = draw(st.lists(st.floats(-1.0, 1.0), min_size=len(m), max_size=len(m)))
        x = sum(ai * np.sin(np.pi * mi * i / n) for ai, mi in zip(a, m))
    x = np.asarray(x, float)
    x[-1] = 0.0
    peak = np.max(np.abs(x))
    return (scale / peak * x if peak > 1e-9 else 0.0 * x), dt


@st.composite
def curve(draw):
    """A static curve through (0, 0), strictly rising: knots 1e-4 ... 0.05 rad apart around 0,
    positive slopes."""
    left = np.cumsum(draw(st.lists(log_float(1e-4, 0.05), min_size=0, max_size=3)))
    right = np.cumsum(draw(st.lists(log_float(1e-4, 0.05), min_size=1, max_size=3)))
    angle = np.r_[-left[::-1], 0.0, right]
    slopes = draw(st.lists(stiffness, min_size=angle.size - 1, max_size=angle.size - 1))
    torque = np.r_[0.0, np.cumsum(np.diff(angle) * slopes)]
    return {"angle": list(angle), "torque": list(torque - torque[left.size])}


@st.composite
def table(draw, start_at_zero=False):
    """A positive lookup table whose values rise away from x = 0 (a knot sits at 0, and for
    the stiffness table at least one on either side), so that its linear extrapolation stays
    positive and k(e) e rises. Tables that fall at an end: see
    test_variable_maxwell_table_extrapolation."""
    sides = [1] if start_at_zero else [-1, 1]
    xs, ys = [0.0], [draw(stiffness)]
    for side in sides:
        n = draw(st.integers(1, 4))
        steps = draw(st.lists(log_float(1e-4, 0.05), min_size=n, max_size=n))
        rises = draw(st.lists(st.floats(0.0, 1e5), min_size=n, max_size=n))
        xs += list(side * np.cumsum(steps))
        ys += list(ys[0] + np.cumsum(rises))
    order = np.argsort(xs)
    return {"x": list(np.array(xs)[order]), "y": list(np.array(ys)[order])}


@st.composite
def element(draw, kind):
    """A valid ``[[element]]`` table of the given kind with random parameters (SI)."""
    if kind == "spring":
        return {"kind": kind, "stiffness": draw(st.floats(0.0, 1e5))}
    if kind == "spring_table":
        return {"kind": kind, **draw(curve())}
    if kind == "cubic_spring":
        return {"kind": kind, "a": draw(st.floats(0.0, 1e8)), "b": draw(st.floats(0.0, 1e5))}
    if kind == "dashpot":
        return {"kind": kind, "damping": draw(log_float(1e-3, 1e3))}
    if kind == "maxwell":
        return {"kind": kind, "stiffness": draw(stiffness), "damping": draw(log_float(1e-3, 1e3))}
    if kind == "prony":
        terms = draw(st.lists(st.fixed_dictionaries({"stiffness": stiffness, "relaxation_time": log_float(1e-5, 10)}),
                              min_size=1, max_size=4))
        return {"kind": kind, "equilibrium_stiffness": draw(st.floats(0.0, 1e5)), "terms": terms}
    if kind == "prandtl":
        return {"kind": kind, "stiffness": draw(stiffness), "yield_torque": draw(log_float(1e-3, 1e3))}
    if kind == "masing":
        el = {"kind": kind, "n": draw(st.integers(1, 12)), "stiffness": draw(stiffness),
              "max_yield_torque": draw(log_float(1e-3, 1e3)), "alpha": draw(st.floats(0.0, 6.0))}
        if draw(st.booleans()):
            el["constriction"] = {"p": draw(log_float(1.0, 1e4)), "k": draw(st.floats(0.0, 2.0))}
        return el
    if kind == "elastoslide":
        el = {"kind": kind, "k": draw(stiffness), "k0": draw(st.floats(0.0, 1e5)), "v_r": draw(log_float(1e-3, 10.0)),
              "p": draw(st.sampled_from([1, 3, 5, 7, 9, 15, 31]))}
        if draw(st.booleans()):
            el.update(phi0=draw(log_float(1e-3, 10.0)), n=draw(st.integers(1, 48)))
        else:
            m = draw(st.integers(1, 6))
            el["distribution"] = {"yield_torque": draw(st.lists(log_float(1e-3, 1e3), min_size=m, max_size=m)),
                                  "weight": draw(st.lists(st.floats(0.01, 1.0), min_size=m, max_size=m))}
        return el
    if kind == "mullins":
        el = {"kind": kind, "tau": draw(log_float(1e-4, 10.0))}
        if draw(st.booleans()):
            k1 = draw(stiffness)
            el["slow_stiffness"] = k1
        else:
            el["slow_curve"] = {"kind": "spring_table", **draw(curve())}
            a, t = np.array(el["slow_curve"]["angle"]), np.array(el["slow_curve"]["torque"])
            i = int(np.searchsorted(a, 0.0, side="right") - 1)
            i = min(i, a.size - 2)
            k1 = (t[i + 1] - t[i]) / (a[i + 1] - a[i])
        el["fast_stiffness"] = k1 * draw(st.floats(1.0, 5.0))
        return el
    if kind == "variable_maxwell":
        el = {"kind": kind}
        spring = draw(st.sampled_from(["gain", "stiffness_table", "force_table"]))
        if spring == "gain":
            el.update(stiffness=draw(stiffness), stiffness_gain=draw(st.floats(0.0, 1e7)))
        elif spring == "stiffness_table":
            el["stiffness_table"] = draw(table())
        else:
            c = draw(curve())
            el["force_table"] = {"x": c["angle"], "y": c["torque"]}
        if draw(st.booleans()):
            el["damping"] = draw(log_float(1e-3, 1e3))
        else:
            el["damping_table"] = draw(table(start_at_zero=True))
        return el
    if kind == "pfeffer":
        el = {"kind": kind, "k1": draw(stiffness), "alpha": draw(log_float(1e-2, 10.0)),
              "beta": draw(st.floats(0.0, 5.0)), "gamma": draw(log_float(1e-5, 1.0))}
        if draw(st.booleans()):
            lo = draw(log_float(1e-5, 1e-2))
            el["friction"] = {"max_torque": draw(log_float(1e-2, 1e3)), "min_yield_angle": lo,
                              "max_yield_angle": lo * draw(st.floats(1.5, 1e3)), "n": draw(st.integers(1, 16))}
        return el
    if kind == "payne":
        el = {"kind": kind, "stiffness": draw(stiffness), "critical_angle": draw(log_float(1e-4, 0.1)),
              "exponent": draw(st.floats(0.2, 2.0)), "loss_stiffness": draw(st.floats(0.0, 1e4)),
              "loss_peak_stiffness": draw(st.floats(0.0, 1e4)), "centre_relaxation_time": draw(log_float(1e-3, 100.0)),
              "memory_time": draw(log_float(1e-3, 10.0))}
        if draw(st.booleans()):
            el.update(storage_frequency_exponent=draw(st.floats(0.0, 1.0)), loss_frequency_exponent=draw(st.floats(0.0, 1.0)),
                      reference_frequency=draw(log_float(0.1, 1e3)))
        return el
    if kind == "filler_network":
        return {"kind": kind, "stiffness": draw(stiffness), "critical_angle": draw(log_float(1e-4, 0.1)),
                "exponent": draw(st.floats(0.2, 2.0)), "breakdown_angle": draw(log_float(1e-4, 1.0)),
                "recovery_time": draw(log_float(1e-3, 100.0)), "centre_relaxation_time": draw(log_float(1e-3, 100.0)),
                "n": draw(st.integers(1, 40))}
    if kind == "power_law":
        lo = draw(log_float(1e-2, 1e3))
        return {"kind": kind, "storage_stiffness": draw(stiffness), "loss_factor": draw(log_float(1e-2, 3.0)),
                "reference_frequency": draw(log_float(0.1, 1e3)), "min_frequency": lo,
                "max_frequency": lo * draw(log_float(1.5, 1e5)), "terms_per_decade": draw(st.floats(0.5, 3.0))}
    if kind == "large_strain_network":
        el = {"kind": kind, "stiffness": draw(st.floats(0.0, 1e5)), "gain": draw(st.floats(0.0, 1e6)),
              "exponent": draw(st.floats(0.5, 4.0)), "network_stiffness": draw(st.floats(0.0, 1e5)),
              "slip": draw(log_float(1e-4, 1.0)), "spread": draw(st.floats(0.2, 4.0)),
              "friction_gain": draw(st.floats(0.0, 1e3)), "damage": draw(st.floats(0.0, 0.95)),
              "damage_angle": draw(log_float(1e-3, 1.0)), "damage_exponent": draw(st.floats(0.2, 4.0)),
              "damage_travel": draw(log_float(1e-3, 10.0)), "n": draw(st.integers(1, 40))}
        if draw(st.booleans()):
            el.update(travel_softening=draw(st.floats(0.0, 5.0)), travel_exponent=draw(st.floats(0.2, 2.0)),
                      slip_hardening=draw(st.floats(0.0, 50.0)), damage_sides=draw(st.booleans()))
        return el
    raise ValueError(kind)


def _steps(x):
    return np.diff(np.r_[0.0, x])


def _slope_range(angle, torque):
    s = np.diff(torque) / np.diff(angle)
    return float(s.max() - s.min())


def nonlinear_bound(el: dict, x: np.ndarray, dt: float) -> float:
    """Bound of |stored + dissipated - trapezoidal work| (J) for one element over the history.

    Per step the discrepancy is the trapezoidal rule's error on the integral of the nonlinear
    spring force f over the spring's deformation step de:
    - |f''| <= M everywhere: |err| <= M |de|^3 / 12;
    - f piecewise linear (tables): only a step containing a knot errs, by <= slope range de^2/4
      (a kink adds at most its slope jump de^2/4 likewise);
    - f monotone: |err| <= |de| |df| / 2, and |de| <= |df| / min f'.
    Linear springs give 0 (and round-off, handled by the caller).
    """
    kind = el["kind"]
    dx = _steps(x)
    if kind == "cubic_spring":  # f = a x^3 + b x, de = dx, f'' = 6 a x
        mid = np.abs(x - dx / 2)
        return float(np.sum(el["a"] * 6 * (mid + np.abs(dx)) * np.abs(dx) ** 3 / 12))
    if kind == "spring_table":
        return float(np.sum(_slope_range(el["angle"], el["torque"]) * dx ** 2 / 4))
    if kind == "mullins" and "slow_curve" in el:
        c = el["slow_curve"]
        return float(np.sum(_slope_range(c["angle"], c["torque"]) * dx ** 2 / 4))
    if kind == "masing" and "constriction" in el:
        # T = S(x) F(x, e): the bank force F (|F| <= F_max, slope <= K_tot, piecewise linear in
        # x with kinks where elements start to slip) scaled by S(x) = (|tanh(Px)| + K)/(1 + K),
        # |S'| <= P/(1+K), |S''| <= 0.77 P^2/(1+K), S' jumps by 2P/(1+K) at x = 0. Its
        # stored energy is S E_bank, not a potential, so the kernel books work minus stored
        # as dissipated: the trapezoidal error of this nonlinear-elastic torque lands there.
        pc, kc = el["constriction"]["p"], el["constriction"]["k"]
        yields = el["max_yield_torque"] * np.exp(el["alpha"] * (np.arange(el["n"]) / max(el["n"] - 1, 1) - 1))
        f_max, k_tot = yields.sum(), el["n"] * el["stiffness"]
        smooth = (0.77 * pc ** 2 * f_max + 2 * pc * k_tot) / (1 + kc)
        kinks = 2 * pc * f_max / (1 + kc) + k_tot
        return float(np.sum(smooth * np.abs(dx) ** 3 / 12 + kinks * dx ** 2 / 4))
    if kind == "large_strain_network":
        return _large_strain_bound(el, x)
    if kind == "variable_maxwell":
        df = _steps(single(el).respond(x, dt))          # the branch's force is its spring's force
        if "force_table" in el:                          # piecewise linear f, slopes s_min ... s_max
            slopes = np.diff(el["force_table"]["y"]) / np.diff(el["force_table"]["x"])
            return float(np.sum((slopes.max() - slopes.min()) * (df / slopes.min()) ** 2 / 4))
        if "stiffness_table" in el:
            fprime = _table_spring_min_slope(el["stiffness_table"], np.max(np.abs(x)))
            return float(np.sum(df ** 2) / (2 * fprime))
        k0, g = el["stiffness"], el["stiffness_gain"]    # f = (k0 + g|e|) e: f' >= k0, |f''| <= 2 g
        return float(np.sum(2 * g * (np.abs(df) / k0) ** 3 / 12))
    return 0.0


def _large_strain_bound(el: dict, x: np.ndarray) -> float:
    """The large-strain network's bound (J): the kernel books its dissipation as the step's
    trapezoidal work minus the change of its stored energy, so what can turn it negative is
    - the trapezoidal error of its elastic torques within a step: the spring's a x |x|^q
      (|f''| = a q (q + 1) |x|^(q-1) for q >= 1; f monotone for any q: |err| <= |dx| |df| / 2)
      and the sticking friction network's kn ((1 + g x^2) S1 + g x S2), S1 = sum e_i, S2 =
      sum e_i^2, whose second derivative is at most kn g n (6 c + 6 |x|) with |e_i| <= c, the
      travel so far (the linear parts have none);
    - a softening within a step that crosses x = 0: a stiffness falling from k0 to k1 books
      (k0 - k1) x0 x1 / 2 there (the travel's k e^(-f c^p), the damage's (1 - D) with
      dD <= D_max |dx| / L).
    A slider's onset books 1/2 k (lim + e0)(1 - s) dx >= 0 in its step (s: the share of the
    step it still sticks), so the sliders add nothing to the bound."""
    dx = _steps(x)
    x0, x1 = np.r_[0.0, x[:-1]], x
    reach = np.maximum(np.abs(x0), np.abs(x1))
    travel = np.cumsum(np.abs(dx))
    a, q, n = el["gain"], el["exponent"], el["n"]
    spring_step = a * (x1 * np.abs(x1) ** q - x0 * np.abs(x0) ** q)
    spring = np.abs(dx) * np.abs(spring_step) / 2
    if q >= 1.0:
        spring = np.minimum(spring, a * q * (q + 1) * reach ** (q - 1) * np.abs(dx) ** 3 / 12)
    network = el["network_stiffness"] * el["friction_gain"] * n * 6 * (travel + reach) * np.abs(dx) ** 3 / 12
    crossing = np.maximum(-x0 * x1, 0.0) / 2
    k, f, p = el["stiffness"], el.get("travel_softening", 0.0), el.get("travel_exponent", 1.0)
    k_travel = k * np.exp(-f * np.r_[0.0, travel] ** p)
    softening = -np.diff(k_travel) + el["damage"] * np.abs(dx) / el["damage_travel"] * (k + a * reach ** q)
    return float(np.sum(spring + network + crossing * softening))


def roundoff_floor(el: dict) -> float:
    """Absolute round-off of the stored energy (J): a static curve's energy is kept as
    trapezoids accumulated from its first knot and shifted to 0 at angle 0, so near angle 0
    it is a difference of numbers of the size of the curve's energy at its ends."""
    c = el.get("slow_curve", el)
    if "angle" not in c:
        return 0.0
    return 1e-14 * len(c["angle"]) * float(np.max(np.abs(np.multiply(c["angle"], c["torque"]))))


def _table_spring_min_slope(tab, reach):
    """min over |e| <= reach of d(k(e) e)/de, k(e) interpolated linearly and held beyond the
    table (as the kernel does)."""
    e = np.linspace(-reach, reach, 20001) if reach > 0 else np.array([-1e-12, 0.0, 1e-12])
    return float(np.min(np.gradient(np.interp(e, tab["x"], tab["y"]) * e, e)))


def check_energy(coupling, element_dicts, x, dt):
    """The three properties of the module docstring for one coupling and one history."""
    r = coupling.simulate(x, dt)
    work = trapezoid_work(x, r.torque_nm)
    # round-off: relative to the work that went through, and 1e-18 J absolute (a table's knot
    # at -2e-18 rad instead of 0 leaves 1e-16 N*m at angle 0)
    scale = np.sum(np.abs(np.diff(np.r_[0.0, work]))) + 1e-9
    floor = 1e-9 * scale + sum(roundoff_floor(el) for el in element_dicts)
    tol = floor + sum(nonlinear_bound(el, x, dt) for el in element_dicts)
    assert np.all(np.isfinite(r.torque_nm))
    assert np.max(np.abs(r.stored_energy_j + r.dissipated_energy_j - work)) <= tol
    assert r.dissipated_energy_j[-1] >= -tol            # over the closed cycle
    assert np.min(r.stored_energy_j) >= -floor           # springs store no negative energy
    assert work[-1] >= -tol
    # the energy records are bookkeeping: without them (as identification runs) the torque is the same
    np.testing.assert_array_equal(coupling.simulate(x, dt, record_energy=False).torque_nm, r.torque_nm)


KINDS = ["spring", "spring_table", "cubic_spring", "dashpot", "maxwell", "prony", "prandtl", "masing",
         "elastoslide", "mullins", "variable_maxwell", "pfeffer", "payne", "power_law", "filler_network",
         "large_strain_network"]


def test_every_kind_is_covered():
    """A new element kind must be added to this property test."""
    from droptower.rheology.elements import ELEMENT_KINDS
    assert sorted(KINDS) == sorted(ELEMENT_KINDS)


@pytest.mark.parametrize("kind", KINDS)
def test_element_passive_and_energy_balanced(kind):
    @SETTINGS
    @given(el=element(kind), history=closed_history())
    def check(el, history):
        x, dt = history
        check_energy(parse_coupling({"element": [el]}), [el], x, dt)

    check()


@pytest.mark.parametrize("path", preset_paths(), ids=lambda p: p.stem)
def test_preset_passive_and_energy_balanced(path):
    import tomllib

    coupling = load_coupling(path)
    elements = tomllib.loads(path.read_text())["element"]
    amplitude, frequency = preset_scale(coupling)

    @settings(SETTINGS, max_examples=max(25, SETTINGS.max_examples // 2))
    @given(history=closed_history(), gain=log_float(0.05, 4.0), rate=log_float(0.1, 10.0))
    def check(history, gain, rate):
        x, dt = history
        # rescale the unit history to the preset's amplitudes and the time step to its frequencies
        x = x / max(np.max(np.abs(x)), 1e-300) * amplitude * gain
        dt = dt * rate * 20.0 / frequency
        check_energy(coupling, elements, x, dt)

    check()


def _load_or_rejected(el):
    """The element, or None if the loader rejects the table as not passive."""
    try:
        return single(el)
    except DroptowerError:
        return None


def test_variable_maxwell_stiffness_table_extrapolation_stays_passive():
    """k = 1000 ... 2000 ... 1000 N*m/rad up to 0.05 rad (positive values only); a slow dashpot
    (1 s) lets the spring follow the angle to 0.1 rad, where a linear extrapolation of the table
    would give -4000 N*m/rad: the element must stay passive (or the table be refused: here
    k(e) e falls between 0.04 and 0.05 rad)."""
    coupling = _load_or_rejected({"kind": "variable_maxwell", "damping": 1000.0,
                                  "stiffness_table": {"x": [-0.05, 0.0, 0.04, 0.05],
                                                      "y": [1000.0, 1000.0, 2000.0, 1000.0]}})
    if coupling is None:
        return
    x = np.interp(np.arange(1, 201), [0, 100, 200], [0.0, 0.1, 0.0])   # 0 -> 0.1 rad -> 0
    r = coupling.simulate(x, 1e-4)
    assert np.min(r.stored_energy_j) >= 0.0
    assert r.dissipated_energy_j[-1] >= 0.0


def test_variable_maxwell_damping_table_extrapolation():
    """c = 10, 10, 8 N*m*s/rad at 0, 1, 2 rad/s (c v rises inside the table); a stiff spring
    (1e5 N*m/rad) makes the dashpot follow a 10 rad/s ramp. A dashpot whose table holds
    values in [8, 10] must then carry between 80 and 100 N*m (a linear extrapolation of the
    table would give c = -8 there, and an earlier kernel returned 0)."""
    coupling = _load_or_rejected({"kind": "variable_maxwell", "stiffness": 1e5,
                                  "damping_table": {"x": [0.0, 1.0, 2.0], "y": [10.0, 10.0, 8.0]}})
    if coupling is None:
        return
    torque = coupling.respond(np.arange(1, 201) * 1e-3, 1e-4)           # 10 rad/s
    assert 80.0 <= torque[-1] <= 100.0


@pytest.mark.parametrize("el", [
    {"kind": "cubic_spring", "a": 1e6, "b": 1000.0},
    {"kind": "variable_maxwell", "stiffness": 2000.0, "stiffness_gain": 1e6, "damping": 20.0},
], ids=["cubic_spring", "variable_maxwell"])
def test_nonlinear_spring_balance_is_second_order(el):
    """Where the balance is not exact it is the trapezoidal rule's O(h^2): on the same smooth
    path (two cycles of a 10 Hz sine, 0.05 rad) the largest discrepancy falls by 4x (3.5 ... 4.5)
    with each halving of the step, and is already < 1e-4 of the peak work at 400 samples/cycle."""
    residual = []
    for spc in (400, 800, 1600):
        t = np.arange(1, 2 * spc + 1) / (10.0 * spc)
        x = 0.05 * np.sin(2 * np.pi * 10.0 * t)
        r = single(el).simulate(x, t[0])
        work = trapezoid_work(x, r.torque_nm)
        residual.append(np.max(np.abs(r.stored_energy_j + r.dissipated_energy_j - work)) / np.max(np.abs(work)))
    assert residual[0] < 1e-4
    assert 3.5 < residual[0] / residual[1] < 4.5 and 3.5 < residual[1] / residual[2] < 4.5
