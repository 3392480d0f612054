"""Couplings of the identification's families drawn at random, and short servo records of
them (shared by the tests and ``benchmarks/bench_identify.py``): wide ranges that keep the drop
tower's first-cycle frequencies at 15-80 Hz for the rig's inertias (0.156-0.523 kg*m^2) with a
few cycles of decay."""
from __future__ import annotations

import numpy as np

#: The reference coupling whose structure the template family fits.
REFERENCE = "rapp2022_nr60"
#: The previous reference coupling (a payne element), whose structure ``random_truth("payne")`` draws.
PAYNE = "rapp2022_nr60_payne"
#: Structures other than the filled_rubber family's own (its acceptance on couplings it was not built from).
OTHER_STRUCTURES = ("masing_fractional", "payne", "zerodim6_friction")
#: Total stiffness range (N*m/rad) that puts the rig's inertias (0.156-0.523 kg*m^2) at 15-80 Hz.
K_RANGE = (6e3, 3e4)


def _log_uniform(rng, lo: float, hi: float) -> float:
    return float(np.exp(rng.uniform(np.log(lo), np.log(hi))))


#: Loss factors at 0.5 deg and 30 Hz a draw must have: the decay loses 12-85 % of its
#: amplitude per cycle (e^(-pi eta)), so a few cycles show it (lighter damping is redrawn).
LOSS_FACTOR_RANGE = (0.04, 0.6)


def random_truth(kind: str, rng) -> dict:
    """A coupling of family ``kind`` drawn from wide ranges that keep the drop tower's decays at
    15-80 Hz with a few cycles (:data:`LOSS_FACTOR_RANGE`; a draw outside is redrawn)."""
    return _within_loss_window(_draw, kind, rng)


def _within_loss_window(draw, kind: str, rng) -> dict:
    """``draw(kind, rng)`` until its loss factor at 0.5 deg and 30 Hz lies in :data:`LOSS_FACTOR_RANGE`."""
    from droptower.rheology import parse_coupling
    from droptower.servo import run_grid

    while True:
        data = draw(kind, rng)
        eta = float(run_grid(parse_coupling(data), [np.radians(0.5)], [30.0], cycles=2, run_in_cycles=3,
                             simulation_rate_hz=9600.0)["loss_factor"].iloc[0])
        if LOSS_FACTOR_RANGE[0] <= eta <= LOSS_FACTOR_RANGE[1]:
            return data


#: Families of the hard draws (:func:`hard_truth`).
HARD_FAMILIES = ("zerodim6", "elastoslide", "masing")


def hard_truth(kind: str, rng) -> dict:
    """A coupling of family ``kind`` from the hard corners of its range (the loss-factor window
    of :func:`random_truth` kept): ``zerodim6``: both Maxwell branches relaxing within a decade
    of the drop tower's first-cycle frequencies (tau 1/(2 pi 10 f_max) .. 10/(2 pi f_min), at
    least 3 x apart), the gain on the fast or on the slow branch (one draw each way);
    ``elastoslide``: p in {3, 5, 7}, v_r 0.05-3 rad/s; ``masing``: a broad yield spread
    (alpha 2-8, yield limits over a decade and a half)."""
    return _within_loss_window(_hard, kind, rng)


def _hard(kind: str, rng) -> dict:
    k = _log_uniform(rng, *K_RANGE)
    if kind == "zerodim6":
        band = (1.0 / (2 * np.pi * 800.0), 10.0 / (2 * np.pi * 15.0))  # a decade beyond 15-80 Hz each way
        t_fast = _log_uniform(rng, band[0], band[1] / 3.0)
        t_slow = _log_uniform(rng, 3.0 * t_fast, band[1])
        k1 = k * rng.uniform(0.4, 0.8)
        kf, ks = (k - k1) * rng.dirichlet([1.0, 1.0])
        gain_on_fast = bool(rng.integers(2))
        (kv, tv), (km, tm) = ((kf, t_fast), (ks, t_slow)) if gain_on_fast else ((ks, t_slow), (kf, t_fast))
        gain = kv * _log_uniform(rng, 1.0, 300.0)  # 1-300 per rad: 2-600 % at 0.02 rad
        return {"name": "hard_zerodim6", "description": f"gain on the {'fast' if gain_on_fast else 'slow'} branch",
                "element": [
            {"kind": "spring", "stiffness": k1}, {"kind": "maxwell", "stiffness": km, "damping": km * tm},
            {"kind": "variable_maxwell", "stiffness": kv, "stiffness_gain": gain, "damping": kv * tv}]}
    if kind == "elastoslide":
        kk = k * rng.uniform(0.6, 1.0)
        return {"name": "hard_elastoslide", "element": [
            {"kind": "elastoslide", "phi0": _log_uniform(rng, 0.004, 0.04), "k": kk, "k0": kk * rng.uniform(0.1, 0.5),
             "v_r": _log_uniform(rng, 0.05, 3.0), "p": int(rng.choice([3, 5, 7])), "n": 32}]}
    if kind == "masing":
        return _masing(rng, k, "hard_masing", (0.001, 0.03), (2.0, 8.0))
    raise ValueError(kind)


def _masing(rng, k: float, name: str, yield_range: tuple[float, float], alpha_range: tuple[float, float]) -> dict:
    """A masing-type coupling of total stiffness ~``k``: yield limits ``yield_range`` of the Prandtl
    stiffness (per element) and spread exponent alpha in ``alpha_range``."""
    n = 7
    kp = k * rng.uniform(0.2, 0.5)
    c1, c2 = k * rng.uniform(0.05, 0.25, 2)
    t1 = _log_uniform(rng, 1.0 / (2 * np.pi * 400.0), 1.0 / (2 * np.pi * 3.0))
    t2 = t1 * _log_uniform(rng, 5.0, 100.0)
    return {"name": name, "element": [
        {"kind": "cubic_spring", "a": k * _log_uniform(rng, 10.0, 1000.0), "b": k * rng.uniform(0.3, 0.6)},
        {"kind": "masing", "n": n, "stiffness": kp / n, "max_yield_torque": kp * _log_uniform(rng, *yield_range) / n,
         "alpha": rng.uniform(*alpha_range)},
        {"kind": "maxwell", "stiffness": c1, "damping": c1 * t1},
        {"kind": "maxwell", "stiffness": c2, "damping": c2 * t2}]}


def truth_vector(kind: str, data: dict) -> np.ndarray:
    """The parameter vector of family ``kind`` (its parameters' order) that IS the coupling ``data``
    (a draw of :func:`hard_truth` or :func:`random_truth`)."""
    e = data["element"]
    if kind == "zerodim6":
        sp, mx, vm = e
        return np.array([sp["stiffness"], mx["stiffness"], mx["damping"] / mx["stiffness"], vm["stiffness"],
                         vm["stiffness_gain"], vm["damping"] / vm["stiffness"]])
    if kind == "elastoslide":
        es = e[0]
        return np.array([es["phi0"], es["k"], es["k0"], es["v_r"], float(es["p"])])
    if kind == "masing":
        cs, ms, m1, m2 = e
        return np.array([cs["a"], cs["b"], ms["stiffness"], ms["max_yield_torque"], ms["alpha"],
                         m1["stiffness"], m1["damping"] / m1["stiffness"], m2["stiffness"], m2["damping"] / m2["stiffness"]])
    raise ValueError(kind)


def _draw(kind: str, rng) -> dict:
    k = _log_uniform(rng, *K_RANGE)
    tau = lambda: _log_uniform(rng, 1.0 / (2 * np.pi * 400.0), 1.0 / (2 * np.pi * 3.0))  # noqa: E731
    if kind == "zerodim6":
        k1 = k * rng.uniform(0.4, 0.8)
        k2, k3 = (k - k1) * rng.dirichlet([1.0, 1.0])
        t3 = tau()
        t2 = t3 * _log_uniform(rng, 5.0, 100.0)  # two distinguishable branches (closer ones merge into one)
        return {"name": "random_zerodim6", "element": [
            {"kind": "spring", "stiffness": k1}, {"kind": "maxwell", "stiffness": k2, "damping": k2 * t2},
            {"kind": "variable_maxwell", "stiffness": k3, "stiffness_gain": rng.uniform(0.0, 1.0) * k3 / 0.01,
             "damping": k3 * t3}]}
    if kind == "elastoslide":
        kk = k * rng.uniform(0.6, 1.0)
        return {"name": "random_elastoslide", "element": [
            {"kind": "elastoslide", "phi0": _log_uniform(rng, 0.004, 0.04), "k": kk, "k0": kk * rng.uniform(0.1, 0.5),
             "v_r": _log_uniform(rng, 0.05, 1.0), "p": int(rng.choice([3, 5, 7, 9])), "n": 32}]}
    if kind == "masing":
        return _masing(rng, k, "random_masing", (0.002, 0.01), (0.5, 3.0))
    if kind == "pfeffer":
        alpha = _log_uniform(rng, 0.1, 1.0)
        return {"name": "random_pfeffer", "element": [
            {"kind": "pfeffer", "k1": k / (1 + alpha), "alpha": alpha, "beta": rng.uniform(0.0, 0.3), "gamma": tau()}]}
    if kind in ("template", "payne"):
        from droptower.identify.data import DataScale
        from droptower.identify.families import TemplateFamily

        reference = REFERENCE if kind == "template" else PAYNE
        fam = TemplateFamily(DataScale(0.02, 0.02, 200.0, 1e4, 1.0, 30.0), {"template": reference})
        factors = np.exp(rng.uniform(np.log(0.6), np.log(1.6), len(fam.parameters)))
        c = fam.coupling(factors)
        return {"name": f"random_{kind}", "element": [e.model_dump(exclude_none=True) for e in c.elements]}
    if kind == "filled_rubber":
        # the filled_rubber family's structure with numbers from wide ranges (its own power-law
        # discretisation: another reference frequency and term spacing than the family's)
        k_eq, k_net = k * rng.uniform(0.2, 0.45), k * rng.uniform(0.3, 0.6)
        crit = _log_uniform(rng, 0.002, 0.01)
        f_min = _log_uniform(rng, 0.1, 3.0)
        return {"name": "random_filled_rubber", "element": [
            {"kind": "cubic_spring", "a": float(rng.choice([0.0, k * _log_uniform(rng, 10.0, 300.0)])), "b": k_eq},
            {"kind": "filler_network", "stiffness": k_net, "critical_angle": crit, "exponent": rng.uniform(0.35, 0.7),
             "breakdown_angle": crit * _log_uniform(rng, 2.0, 8.0), "n": 32},
            {"kind": "power_law", "storage_stiffness": k * rng.uniform(0.02, 0.1), "loss_factor": rng.uniform(0.3, 2.0),
             "reference_frequency": 30.0, "min_frequency": f_min, "max_frequency": f_min * 10 ** rng.uniform(3.0, 4.0),
             "terms_per_decade": 1.5}]}
    if kind == "masing_fractional":
        # a friction bank (Masing) beside a fractional branch spread over three to five decades
        n = 7
        kp, kb = k * rng.uniform(0.2, 0.4), k * rng.uniform(0.05, 0.2)
        f_min = _log_uniform(rng, 0.05, 3.0)
        return {"name": "random_masing_fractional", "element": [
            {"kind": "cubic_spring", "a": k * _log_uniform(rng, 10.0, 1000.0), "b": k * rng.uniform(0.3, 0.6)},
            {"kind": "masing", "n": n, "stiffness": kp / n, "max_yield_torque": kp * _log_uniform(rng, 0.002, 0.01) / n,
             "alpha": rng.uniform(0.5, 3.0)},
            {"kind": "power_law", "storage_stiffness": kb, "loss_factor": rng.uniform(0.1, 0.6),
             "reference_frequency": 30.0, "min_frequency": f_min, "max_frequency": f_min * 10 ** rng.uniform(3.0, 5.0),
             "terms_per_decade": 2.0}]}
    if kind == "zerodim6_friction":
        # the six-parameter form with a friction bank (Prandtl elements) beside it
        six = _draw("zerodim6", rng)["element"]
        kp, n = k * rng.uniform(0.1, 0.3), 5
        six.append({"kind": "masing", "n": n, "stiffness": kp / n,
                    "max_yield_torque": kp * _log_uniform(rng, 0.002, 0.01) / n, "alpha": rng.uniform(0.5, 3.0)})
        return {"name": "random_zerodim6_friction", "element": six}
    raise ValueError(kind)


def servo_records(truth, seed: int) -> list:
    """The zero-dimensional model paper's test types in short (slow ramps, a frequency and an
    amplitude sweep, a band-limited random profile: about 9 s at 2048 Hz) driving ``truth``,
    with 0.5 % white noise (seeded) on the torque."""
    from droptower.identify.data import make_segment
    from droptower.servo import histories as H

    fs, d = 2048.0, np.radians
    hs = {"ramps": H.ramps(d(3.0), d(4.0), fs),
          "frequency_sweep": H.frequency_sweep([5.0, 10.0, 15.0, 20.0, 25.0], d(1.0), fs, run_in_cycles=2, cycles=2),
          "amplitude_sweep": H.amplitude_sweep(d(np.array([0.3, 1.0, 2.0, 3.0])), 15.0, fs, run_in_cycles=2,
                                               cycles=2),
          "random": H.random_profile(d(1.0), (0.5, 25.0), 5.0, fs, seed=11)}
    rng = np.random.default_rng(seed)
    torques = {k: truth.respond(h.angle_rad, h.dt_s) for k, h in hs.items()}
    sigma = 0.005 * max(np.abs(t).max() for t in torques.values())
    return [make_segment(h.time_s, h.angle_rad, torques[k] + rng.normal(0, sigma, torques[k].size), name=k)
            for k, h in hs.items()]
