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



def _drop_damping_ratio(k: float, c: float, j: float) -> float:
    """Rapp's d of the free decay of a Kelvin-Voigt coupling (k, c) on inertia j (docs/theory.md#decay)."""
    delta = c / (2 * j)
    omega = math.sqrt(k / j - delta ** 2)
    return 0.5 * (math.exp(4 * math.pi * delta / omega) - 1)

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
        d = _drop_damping_ratio(k, c, j)
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


# ---- the model route for real: identification from the drops, the virtual bench -------------------
#: the rig a route campaign's extraction reads with (nominal lever length and laser radius, m)
LEVER_M, LASER_M = 0.2, 0.25
#: the stated input uncertainties of a route campaign: J per fixture, lever, laser, flange, force sensor, clock
ROUTE_STATED = RigUncertainty(
    inertias_kgm2=[FixtureUncertainty(nominal=j, value=0.01 * j) for j in FIXTURES],       # 1 % each
    lever_length_m=InputUncertainty(value=0.005 * LEVER_M),                                   # 0.5 %
    laser_radius_m=InputUncertainty(value=0.005 * LASER_M),                                   # 0.5 %
    laser_calibration_rel=InputUncertainty(value=0.005),
    torque_calibration_rel=InputUncertainty(value=0.01),
    force_calibration_rel=InputUncertainty(value=0.005),
    sample_rate_hz=InputUncertainty(value=2e-3 * FS),                                         # 0.2 % clock
)


def _template(folder) -> str:
    """A Kelvin-Voigt coupling file as the template family's structure (its numbers only a start)."""
    from pathlib import Path

    from droptower.rheology import coupling_to_toml, parse_coupling

    path = Path(folder) / "kelvin_voigt.toml"
    if not path.exists():
        path.write_text(coupling_to_toml(parse_coupling({"element": [{"kind": "spring", "stiffness": 1.5e4},
                                                                       {"kind": "dashpot", "damping": 10.0}]})))
    return str(path)


def route_campaign(seed: int, drops_per_fixture: int = 1, stated: RigUncertainty = ROUTE_STATED,
                   folder: str | None = None, duration_s: float = 0.06) -> dict[str, float]:
    """One virtual campaign through the package's model route: a Kelvin-Voigt coupling's drops on
    a rig drawn from ``stated`` (J per fixture, lever, laser radius and calibration, flange, force
    sensor, clock: one draw shared by every drop), read with the NOMINAL rig, identified with the
    template family (:func:`~droptower.identify.drop_campaign.identify_from_drop_tests`), run on the
    virtual bench at :data:`SERVO_HZ` (:func:`~droptower.compare.model_map.model_map_from_identification`,
    its cluster-robust band) with the inputs' shares (:func:`droptower.uncertainty.route.route_input_sets`).
    Returns K' (N·m/deg) and η with their U95 with the inputs and fit-only, and the truth."""
    import tempfile

    from droptower.compare.model_map import model_map_from_identification
    from droptower.identify.dropfit import DropFitSettings
    from droptower.identify.droplogs import ReadSettings, decay_from_signals
    from droptower.identify.drop_campaign import DropCampaign, identify_from_drop_tests

    rng = np.random.default_rng(seed)
    k = rng.uniform(1.2e4, 2.5e4)
    c = rng.uniform(8.0, 25.0)
    true_j = {j: rng.normal(j, stated.inertia(j).standard) for j in FIXTURES}
    lever = rng.normal(LEVER_M, stated.lever_length_m.standard)
    laser = rng.normal(LASER_M, stated.laser_radius_m.standard)
    kappa = {name: rng.normal(1.0, getattr(stated, name).standard)
             for name in ("laser_calibration_rel", "torque_calibration_rel", "force_calibration_rel")}
    fs = rng.normal(FS, stated.sample_rate_hz.standard)
    decays, amps = [], []
    for j_nom in FIXTURES:
        j = true_j[j_nom]
        d = _drop_damping_ratio(k, c, j)
        for r in range(drops_per_fixture):
            drop = SyntheticDrop(inertia_kgm2=j, stiffness_nm_per_rad=k, damping_ratio=d, lever_length_m=lever,
                                 amplitude_deg=rng.uniform(0.5, 2.5), sample_rate_hz=fs, duration_s=duration_s,
                                 pretrigger_s=0.01, seed=int(rng.integers(2 ** 31)))
            time, ch = drop.channels()
            # the logger labels its samples at the nominal rate; the laser's distance s = r·φ read
            # through r_0 and its calibration, the flange and the force sensor through theirs
            signals = DropSignals(np.arange(time.size) / FS, ch["angle_rad"] * laser / LASER_M * kappa["laser_calibration_rel"],
                                  ch["torque_nm"] * kappa["torque_calibration_rel"],
                                  ch["impact_force_n"] * kappa["force_calibration_rel"],
                                  metadata={"inertia_kgm2": j_nom, "lever_length_m": LEVER_M})
            decays.append(decay_from_signals(signals, ReadSettings(), f"drop_{j_nom:g}_{r}"))
            amps.append(math.degrees(decays[-1].amplitude_rad))
    with tempfile.TemporaryDirectory() if folder is None else _Keep(folder) as where:
        campaign = DropCampaign(decays, [], DropFitSettings(holdout_fraction=0.0, conditioning=None),
                                {"template": _template(where)}, ReadSettings())
        ident = identify_from_drop_tests(campaign, "template")
    mm = model_map_from_identification(ident, decays, campaign.settings, uncertainty=stated, lever_length_m=LEVER_M,
                                       laser_radius_m=LASER_M)
    a = float(np.median(amps))
    row = mm.evaluate([a], [SERVO_HZ]).iloc[0]
    shares = mm.input_shares([a], [SERVO_HZ])
    out = {"k_true": math.radians(k), "eta_true": c * 2 * math.pi * SERVO_HZ / k}
    for name, q in (("k", "storage_stiffness_nm_per_deg"), ("eta", "loss_factor")):
        out[name] = float(row[q])
        out[f"{name}_U95_fit"] = 2 * float(row[f"{q}_std"])
        out[f"{name}_U95"] = float(row[f"{q}_U95"])
        out[f"{name}_dominant"] = max(shares[q], key=lambda key: abs(shares[q][key][0]))
    out["converged"] = float(ident.converged)
    return out


class _Keep:
    """A folder kept (the template written once for many campaigns)."""

    def __init__(self, folder: str) -> None:
        self.folder = folder

    def __enter__(self) -> str:
        return self.folder

    def __exit__(self, *exc) -> None:
        return None


def route_coverage(campaigns: int, seed: int = 0, drops_per_fixture: int = 1, folder: str | None = None) -> dict[str, float]:
    """Share of ``campaigns`` route campaigns whose interval holds the truth (K', η; with the inputs, fit-only)."""
    hits = {"k": 0, "eta": 0, "k_fit": 0, "eta_fit": 0}
    for i in range(campaigns):
        r = route_campaign(seed + i, drops_per_fixture, folder=folder)
        for q in ("k", "eta"):
            err = abs(r[q] - r[f"{q}_true"])
            hits[q] += err <= r[f"{q}_U95"]
            hits[f"{q}_fit"] += err <= r[f"{q}_U95_fit"]
    return {name: n / campaigns for name, n in hits.items()}
