"""Lehr's D and the loss factor beside Rapp's d: the sdof conversions against the closed forms of
J φ'' + d φ' + c φ = 0, and the three side by side in extract, the condition summary and validate."""
from __future__ import annotations

import numpy as np
import pandas as pd
from hypothesis import given, settings, strategies as st

from droptower import sdof
from droptower.extract.result import OUTPUTS
from droptower.maps.summary import condition_summary


@settings(max_examples=200, derandomize=True, deadline=None)
@given(st.floats(1e-3, 10.0), st.floats(1e2, 1e5), st.floats(1e-4, 0.9))
def test_lehr_damping_of_a_viscous_oscillator(inertia, stiffness, lehr):
    # closed form: d_visc = 2 D sqrt(J c), delta = d_visc / 2J, omega = sqrt(c/J - delta^2)
    damping = 2.0 * lehr * np.sqrt(inertia * stiffness)
    delta = damping / (2.0 * inertia)
    omega = np.sqrt(stiffness / inertia - delta**2)
    assert np.isclose(sdof.lehr_damping(delta, omega), lehr, rtol=1e-9)
    # the stiffness the extractor derives from the same decay is c (eq. 15)
    assert np.isclose(sdof.stiffness(inertia, omega, delta), stiffness, rtol=1e-9)
    # eta = K''/K' = d_visc omega / c of the Kelvin-Voigt coupling at its damped frequency
    assert np.isclose(sdof.loss_factor(delta, omega), damping * omega / stiffness, rtol=1e-9)
    # and the same two from Rapp's d alone
    lehr_d, eta_d = sdof.damping_measures(sdof.damping_ratio(delta, omega))
    assert np.isclose(lehr_d, lehr, rtol=1e-7) and np.isclose(eta_d, damping * omega / stiffness, rtol=1e-7)


def test_published_pair():
    # docs/theory.md#damping-measures: r = 0.1 -> d = 1.26 (the theory page: about 1.25), D = 0.0995, eta = 0.198
    d = sdof.damping_ratio(0.1, 1.0)
    lehr, eta = sdof.damping_measures(d)
    assert np.isclose(d, 0.5 * np.expm1(0.4 * np.pi)) and 1.25 < d < 1.26
    assert np.isclose(lehr, 0.1 / np.sqrt(1.01)) and np.isclose(eta, 0.2 / 1.01)


def test_extract_outputs_carry_all_three():
    assert {"damping_ratio", "lehr_damping", "loss_factor"} <= set(OUTPUTS)


def test_condition_summary_carries_all_three():
    d = np.array([1.2, 1.4, 0.5])
    results = pd.DataFrame({"case": ["a", "a", "b"], "inertia_kgm2": 0.1, "drop_mass_kg": 2.0, "drop_height_m": 0.4,
                            "preload_nm": 0.0, "amplitude_deg": [1.0, 1.0, 2.0], "frequency_hz": 30.0,
                            "stiffness_nm_per_deg": 100.0, "damping_ratio": d, "status": "done", "flags": ""})
    summary = condition_summary(results)
    lehr, eta = sdof.damping_measures(d)
    assert np.allclose(summary["lehr_damping_mean"], [lehr[:2].mean(), lehr[2]])
    assert np.allclose(summary["loss_factor_mean"], [eta[:2].mean(), eta[2]])
    assert np.allclose(summary["damping_ratio_mean"], [1.3, 0.5])


def test_map_gives_all_three():
    from droptower.data import read_table4
    from droptower.maps import fit_map

    fit = fit_map(read_table4())
    a, f = np.array([0.5, 1.0, 2.0]), np.array([25.0, 35.0, 45.0])
    lehr, eta = sdof.damping_measures(fit.damping_ratio(a, f))
    assert np.allclose(fit.lehr_damping(a, f), lehr) and np.allclose(fit.loss_factor(a, f), eta)
    assert "d = E_diss/E_el (Rapp et al. 2022)" in fit.summary()
