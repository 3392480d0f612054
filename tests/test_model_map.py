"""The model-based characteristic map (droptower.compare.model_map): linear couplings against the
closed form K*(iω) and the d of the complex root, confidence bands from a drop-test
identification (they shrink with more tests and cover the truth on seeded draws), the JSON
round trip and the two-route validation."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from droptower.compare.model_map import (ModelMap, damping_measures, model_map_from_coupling,
                                         model_map_from_identification)
from droptower.identify.dropfit import DropFitSettings, identify_drops
from droptower.identify.droplogs import DropDecay
from droptower.identify.lever import free_decay
from droptower.maps.mapfit import MapRange
from droptower.rheology import coupling_to_toml, parse_coupling

RANGE = MapRange(0.3, 3.0, 20.0, 60.0)


def kelvin_voigt(c: float, d: float):
    return parse_coupling({"element": [{"kind": "spring", "stiffness": c}, {"kind": "dashpot", "damping": d}]})


def complex_root_damping(c: float, d: float, omega: float) -> tuple[float, float]:
    """(Rapp's d, Lehr's D) of the free decay J φ'' + d φ' + c φ = 0 whose damped frequency is ω:
    J from ω² = c/J − (d/2J)² (docs/theory.md#decay), then δ = d/2J, eq. 16."""
    j = (c + math.sqrt(c * c - omega * omega * d * d)) / (2 * omega * omega)
    delta = d / (2 * j)
    return 0.5 * math.expm1(4 * math.pi * delta / omega), delta / math.sqrt(omega * omega + delta * delta)


def test_kelvin_voigt_map_is_the_closed_form_and_the_complex_root():
    c, d = 20000.0, 25.0
    mm = model_map_from_coupling(kelvin_voigt(c, d), RANGE)
    a, f = np.array([0.5, 1.5, 2.5, 0.5]), np.array([5.0, 20.0, 45.0, 100.0])
    t = mm.evaluate(a, f)
    w = 2 * np.pi * f
    # the bench's fine step (>= 4096 per cycle) shifts K' by K'' w h / 2 <= pi / 4096 of K''
    assert t["storage_stiffness_nm_per_deg"].to_numpy() == pytest.approx(np.radians(c) * np.ones(4), rel=1e-3)
    assert t["loss_stiffness_nm_per_deg"].to_numpy() == pytest.approx(np.radians(d * w), rel=1e-3)
    assert t["loss_factor"].to_numpy() == pytest.approx(d * w / c, rel=1e-3)
    assert t["dynamic_stiffness_nm_per_deg"].to_numpy() == pytest.approx(np.radians(np.abs(c + 1j * d * w)), rel=1e-3)
    for row, omega in zip(t.itertuples(), w):
        d_root, lehr_root = complex_root_damping(c, d, omega)
        # compared through r = ln(1 + 2d) / 4 pi (eq. 16 inverted): d = (e^(4 pi r) - 1) / 2 magnifies
        # the bench's 1e-3 in eta tenfold at r ~ 0.5 (the 100 Hz point, d ~ 220)
        assert math.log1p(2 * row.drop_tower_equivalent_damping_ratio) == pytest.approx(math.log1p(2 * d_root), rel=1.5e-3)
        assert row.lehr_damping == pytest.approx(lehr_root, rel=1.5e-3)


@settings(max_examples=6, deadline=None, derandomize=True)
@given(k=st.floats(5e3, 5e4), ratio=st.floats(0.1, 1.0), tau_ms=st.floats(0.2, 50.0),
       amplitude=st.floats(0.1, 5.0), frequency=st.floats(2.0, 80.0))
def test_spring_and_maxwell_map_is_k_star_of_i_omega(k, ratio, tau_ms, amplitude, frequency):
    """K*(iω) = k + k_m iωτ / (1 + iωτ) at random parameter sets and points."""
    tau, k_m = tau_ms * 1e-3, ratio * k
    coupling = parse_coupling({"element": [{"kind": "spring", "stiffness": k},
                                           {"kind": "maxwell", "stiffness": k_m, "damping": k_m * tau}]})
    t = model_map_from_coupling(coupling, RANGE).evaluate([amplitude], [frequency])
    iwt = 1j * 2 * math.pi * frequency * tau
    exact = k + k_m * iwt / (1 + iwt)
    scale = math.radians(abs(exact))
    assert t["storage_stiffness_nm_per_deg"].iloc[0] == pytest.approx(math.radians(exact.real), abs=1e-3 * scale)
    assert t["loss_stiffness_nm_per_deg"].iloc[0] == pytest.approx(math.radians(exact.imag), abs=1e-3 * scale)
    d, lehr = damping_measures(exact.imag / exact.real)
    assert t["drop_tower_equivalent_damping_ratio"].iloc[0] == pytest.approx(float(d), rel=5e-3, abs=1e-5)
    assert t["lehr_damping"].iloc[0] == pytest.approx(float(lehr), rel=5e-3, abs=1e-6)


def test_fast_maxwell_map_d_is_the_complex_roots():
    """Relaxation far faster than the oscillation: the map's d (of K*(iω)) is the d of the
    complex root of J s² + K*(s) = 0, within what K*(s) differs from K*(iω) (here < 1 %)."""
    k, k_m, tau, j = 11000.0, 3000.0, 1e-4, 0.359
    coupling = parse_coupling({"element": [{"kind": "spring", "stiffness": k},
                                           {"kind": "maxwell", "stiffness": k_m, "damping": k_m * tau}]})
    s = 1j * math.sqrt((k + k_m) / j)
    for _ in range(50):
        s -= (j * s * s + k + k_m * tau * s / (1 + tau * s)) / (2 * j * s + k_m * tau / (1 + tau * s) ** 2)
    d_root = 0.5 * math.expm1(4 * math.pi * -s.real / s.imag)
    t = model_map_from_coupling(coupling, RANGE).evaluate([1.0], [s.imag / (2 * math.pi)])
    assert t["drop_tower_equivalent_damping_ratio"].iloc[0] == pytest.approx(d_root, rel=0.01)


# ---- bands from a drop-test identification -------------------------------------------------
TRUTH = (20000.0, 20.0)
DT = 1 / 9600
NOISE = 2e-3  # of each test's amplitude: the fit is noise-limited


def synthetic_decays(n_tests: int, seed: int) -> list[DropDecay]:
    """Free decays of the Kelvin-Voigt truth on the identification's own lever model, with white
    angle noise (seeded): the fitted family is exact, so the bands' coverage is statistics alone."""
    rng = np.random.default_rng(seed)
    truth = kelvin_voigt(*TRUTH)
    inertia = np.resize([0.1557, 0.359, 0.5233], n_tests)
    rate = np.resize([0.5, 1.5, 3.0, 6.0], n_tests) * (1 + 0.05 * np.arange(n_tests) / n_tests)
    n = int(0.06 / DT)
    angle, torque = free_decay(truth, inertia, rate, n, DT)
    out = []
    for i in range(n_tests):
        amp = float(np.max(np.abs(angle[i])))
        noisy = angle[i, 1:] + NOISE * amp * rng.standard_normal(n)
        f = math.sqrt(TRUTH[0] / inertia[i]) / (2 * math.pi)
        out.append(DropDecay(f"test_{i}", np.arange(1, n + 1) * DT, noisy, None, float(inertia[i]), float(rate[i]),
                             "impact_force", f, amp, DT, angle_noise_rad=NOISE * amp))
    return out


def identified_map(n_tests: int, seed: int, tmp_path) -> ModelMap:
    template = tmp_path / "kv.toml"
    template.write_text(coupling_to_toml(kelvin_voigt(15000.0, 30.0)))
    decays = synthetic_decays(n_tests, seed)
    fit_settings = DropFitSettings(conditioning=None, holdout_fraction=0.0, seed=seed)
    ident = identify_drops("template", decays, settings=fit_settings, options={"template": str(template)})
    assert ident.converged
    return model_map_from_identification(ident, decays, fit_settings, tested=RANGE)


POINT = ([1.0], [30.0])


@pytest.mark.slow
def test_bands_shrink_with_more_tests(tmp_path):
    few = identified_map(4, 1, tmp_path).evaluate(*POINT)
    many = identified_map(16, 1, tmp_path).evaluate(*POINT)
    for q in ("storage_stiffness_nm_per_deg", "loss_factor", "drop_tower_equivalent_damping_ratio"):
        assert many[f"{q}_std"].iloc[0] < 0.75 * few[f"{q}_std"].iloc[0], q  # ~1/sqrt(4) expected


@pytest.mark.slow
def test_bands_cover_the_truth_on_seeded_draws(tmp_path):
    """95 % bands at one point over 20 noise draws: at most a few misses (P(>= 5 misses) < 2 % for
    a true 95 % band), and not all bands hugely wide (their width is within 3x the draws' spread)."""
    exact = model_map_from_coupling(kelvin_voigt(*TRUTH), RANGE).evaluate(*POINT)
    misses, widths, values = {}, {}, {}
    for seed in range(20):
        t = identified_map(8, 100 + seed, tmp_path).evaluate(*POINT)
        for q in ("storage_stiffness_nm_per_deg", "loss_factor"):
            lo, hi, truth = t[f"{q}_band_lo"].iloc[0], t[f"{q}_band_hi"].iloc[0], exact[q].iloc[0]
            misses[q] = misses.get(q, 0) + int(not lo <= truth <= hi)
            widths.setdefault(q, []).append(t[f"{q}_std"].iloc[0])
            values.setdefault(q, []).append(t[q].iloc[0])
    for q in misses:
        assert misses[q] <= 4, (q, misses[q])
        assert np.median(widths[q]) < 3 * np.std(values[q], ddof=1), q


@pytest.mark.slow
def test_json_round_trip(tmp_path):
    mm = identified_map(6, 3, tmp_path)
    grid = mm.evaluate_grid(n=(3, 2))
    path = tmp_path / "model_map.json"
    mm.to_json(path)
    back = ModelMap.from_json(path)
    assert back.route == "model-based map, template" == mm.route
    assert back.band_method == mm.band_method and back.range == mm.range
    np.testing.assert_allclose(back.band_sets, mm.band_sets, rtol=1e-15)
    np.testing.assert_allclose(back.coupling.params, mm.coupling.params, rtol=1e-15)
    assert back.grid.equals(grid)
    again = back.evaluate(grid["amplitude_deg"], grid["frequency_hz"])
    for col in ("storage_stiffness_nm_per_deg", "loss_factor_band_hi"):
        np.testing.assert_allclose(again[col], grid[col], rtol=1e-12)


def test_malformed_model_map_is_one_line_error(tmp_path):
    from droptower.errors import DroptowerError

    bad = tmp_path / "m.json"
    bad.write_text('{"format": "droptower-model-map", "format_version": 1}')
    with pytest.raises(DroptowerError, match="malformed model map"):
        ModelMap.from_json(bad)
    bad.write_text('{"format": "droptower-map"}')
    with pytest.raises(DroptowerError, match="not a droptower-model-map"):
        ModelMap.from_json(bad)
