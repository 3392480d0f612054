"""Virtual campaigns for the coverage of the model route (shared by
tests/test_uncertainty_route_coverage.py and ``benchmarks/bench_uncertainty_coverage.py``).

A cheap faithful setting: a linear Kelvin-Voigt coupling (stiffness k, damping constant c),
whose servo K' = k and loss factor η = c·ω_s/k are the truth at every servo frequency, and
whose drops are exact linear decays (:class:`~droptower.extract.SyntheticDrop`, sensor noise
included). Each campaign draws ONE rig from the stated uncertainties (one J per fixture, one
sample clock: shared by every drop of the campaign, as in a lab), logs its drops as the nominal
rig reads them and extracts them with the NOMINAL rig. The model route of this coupling has a
closed form: each drop gives k_i = J(ω_i² + δ_i²) and η_i(ω_s) = 2δ_i·ω_s/(ω_i² + δ_i²) (J
cancels), the route pools them by their mean. Its uncertainty: the fit's share from each drop's
fit covariance (independent drops, shrinks as 1/n), and the inputs' from each drop's GUM
sensitivities (droptower.uncertainty.drop_budget), added COHERENTLY over the drops that share
the input (one J per fixture, one clock for all), then in quadrature across inputs.
"""
from __future__ import annotations

import math

import numpy as np

from droptower.extract import SyntheticDrop, extract
from droptower.io.signals import DropSignals
from droptower.propagation import propagate
from droptower.rig.uncertainty import FixtureUncertainty, InputUncertainty, RigUncertainty
from droptower.uncertainty import drop_budget

FIXTURES = (0.1557, 0.359, 0.5233)
FS = 38_400.0
SERVO_HZ = 10.0
STATED = RigUncertainty(
    inertias_kgm2=[FixtureUncertainty(nominal=j, value=0.01 * j) for j in FIXTURES],   # 1 % each
    sample_rate_hz=InputUncertainty(value=2e-3 * FS),                                  # 0.2 % clock
)


def campaign(seed: int, drops_per_fixture: int = 2, stated: RigUncertainty = STATED) -> dict[str, float]:
    """One virtual campaign: the model route's K' and η at :data:`SERVO_HZ` with their U95, with
    the inputs (``*_U95``) and without (``*_U95_fit``), and the truth."""
    rng = np.random.default_rng(seed)
    k = rng.uniform(1.2e4, 2.5e4)
    c = rng.uniform(8.0, 25.0)                       # N·m·s/rad: d from ~0.8 to ~3 on these fixtures
    true_j = {j: rng.normal(j, stated.inertia(j).standard) for j in FIXTURES}
    fs = rng.normal(FS, stated.sample_rate_hz.standard)
    w_s = 2 * math.pi * SERVO_HZ
    ks, etas, u_k_fit, u_eta_fit = [], [], [], []
    sens_k: dict[str, list[float]] = {}
    sens_eta: dict[str, list[float]] = {}
    for j_nom in FIXTURES:
        j = true_j[j_nom]
        delta = c / (2 * j)
        omega = math.sqrt(k / j - delta ** 2)
        d = 0.5 * (math.exp(4 * math.pi * delta / omega) - 1)
        for _ in range(drops_per_fixture):
            drop = SyntheticDrop(inertia_kgm2=j, stiffness_nm_per_rad=k, damping_ratio=d,
                                 amplitude_deg=rng.uniform(0.5, 2.5), sample_rate_hz=fs, duration_s=0.1,
                                 seed=int(rng.integers(2 ** 31)))
            time, ch = drop.channels()
            # the logger labels its samples at the nominal rate; the extraction takes the nominal J
            signals = DropSignals(np.arange(time.size) / FS, ch["angle_rad"], ch["torque_nm"], ch["impact_force_n"],
                                  metadata={"inertia_kgm2": j_nom, "lever_length_m": drop.lever_length_m})
            result = extract(signals)
            budget = drop_budget(result, stated, metadata=signals.metadata, method="gum")
            theta = result.angle_fit.params  # (φ̂, δ, ω, Φ)

            def eta_of(th: np.ndarray) -> np.ndarray:
                return np.array([2 * th[1] * w_s / (th[2] ** 2 + th[1] ** 2)])

            eta_i, u_i = propagate(eta_of, theta, result.angle_fit.cov)
            ks.append(result.stiffness_nm_per_rad)
            etas.append(float(eta_i[0]))
            u_k_fit.append(budget["stiffness_nm_per_rad"].contributions["fit"])
            u_eta_fit.append(float(u_i[0]))
            # signed first-order shares: k ∝ J and ∝ f_s² (c = J(ω² + δ²)); η ∝ 1/f_s (δ, ω ∝ f_s)
            for name, shares, value in (("k", sens_k, ks[-1]), ("eta", sens_eta, etas[-1])):
                for f in FIXTURES:
                    key = f"inertia_kgm2@{f:g}"
                    shares.setdefault(key, []).append(value * stated.inertia(f).standard / f
                                                      if name == "k" and f == j_nom else 0.0)
                shares.setdefault("sample_rate_hz", []).append(
                    value * stated.sample_rate_hz.standard / FS * (2.0 if name == "k" else -1.0))
    n = len(ks)
    out = {"k_true": k, "eta_true": c * w_s / k, "k": float(np.mean(ks)), "eta": float(np.mean(etas))}
    for name, u_fit, sens in (("k", u_k_fit, sens_k), ("eta", u_eta_fit, sens_eta)):
        fit = math.sqrt(sum(u * u for u in u_fit)) / n                    # independent drops: the mean's
        inputs = math.sqrt(sum((sum(v) / n) ** 2 for v in sens.values()))  # coherent over the drops sharing it
        out[f"{name}_U95_fit"] = 2 * fit
        out[f"{name}_U95"] = 2 * math.hypot(fit, inputs)
    return out


def coverage(campaigns: int, seed: int = 0, drops_per_fixture: int = 2) -> dict[str, float]:
    """Share of ``campaigns`` whose interval holds the truth: K' and η, with the inputs and fit-only."""
    hits = {"k": 0, "eta": 0, "k_fit": 0, "eta_fit": 0}
    for i in range(campaigns):
        r = campaign(seed + i, drops_per_fixture)
        for q in ("k", "eta"):
            err = abs(r[q] - r[f"{q}_true"])
            hits[q] += err <= r[f"{q}_U95"]
            hits[f"{q}_fit"] += err <= r[f"{q}_U95_fit"]
    return {name: n / campaigns for name, n in hits.items()}
