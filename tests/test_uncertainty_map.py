"""The map's expanded uncertainties (droptower.uncertainty.mapband): the fit's share and the
rig's inputs' share, the inputs correlated across the drops that share them."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from droptower.maps import fit_map
from droptower.rig.uncertainty import override_uncertainty
from droptower.uncertainty import map_uncertainty
from test_maps import synthetic_table

#: the same tests' map fitted once per process by this module's commands and calls (tests/conftest.py)
pytestmark = pytest.mark.usefixtures("shared_map_fits")

A = np.array([0.2, 0.5, 1.0, 2.0])
F = np.array([40.0, 30.0, 25.0, 22.0])
FIXTURES = (0.1557, 0.359, 0.5233)


def _repeats(n: int, noise: float = 0.02) -> pd.DataFrame:
    return pd.concat([synthetic_table(noise, seed=s) for s in range(n)], ignore_index=True)


def test_one_inertia_error_for_every_fixture_scales_the_stiffness_map_and_not_its_damping():
    """Every fixture's J off by the same relative u: every stiffness c = J(ω² + δ²) scales by it,
    so does the map's (u(c)/c = u_J/J exactly, first order); the damping ratio carries no J."""
    table = synthetic_table(0.02)
    one = override_uncertainty(None, [f"inertia_kgm2@{j}={0.01 * j}" for j in FIXTURES])
    mu = map_uncertainty(table, one)
    total = sum(mu.sensitivity.values())  # fully correlated: the three move together
    m, p = mu.map, np.concatenate([mu.map.stiffness_params, mu.map.ratio_params])
    moved = m.form.stiffness.value((p + 1e-3 * total)[:7], A, F)
    np.testing.assert_allclose((moved / m.stiffness_nm_per_deg(A, F) - 1) / 1e-3, 0.01, rtol=1e-3)
    step = p + 1e-3 * total
    damping = m.form.stiffness.value(step[:7], A, F) / m.form.ratio.value(step[7:], A, F)
    assert np.all(np.abs(damping / m.damping_ratio(A, F) - 1) / 1e-3 < 1e-6)  # J moves no damping ratio
    assert mu.not_given == ("sample_rate_hz", "laser_radius_m", "laser_calibration_rel")
    # U95 = 2·u_c, u_c² = u_fit² + u_inputs²; u_fit is the map's own coefficient uncertainty
    coef = mu.coefficient_table()
    np.testing.assert_allclose(coef["u_fit"], list(m.uncertainties.values()), rtol=1e-9)
    np.testing.assert_allclose(coef["U95"], 2 * np.hypot(coef["u_fit"], coef["u_inputs"]))


def test_one_fixtures_share_is_what_refitting_the_moved_drops_gives():
    """The sensitivity of the map to one fixture's J (implicit function theorem) against the
    map fitted anew to that fixture's stiffnesses moved by 0.1 %."""
    table = synthetic_table(0.02)
    mu = map_uncertainty(table, override_uncertainty(None, ["inertia_kgm2@0.359=0.00359"]))  # 1 %
    moved = table.copy()
    moved.loc[np.isclose(moved["inertia_kgm2"], 0.359), "stiffness_nm_per_deg"] *= 1.001
    refit = fit_map(moved, form=mu.map.form)
    pred = mu.predict(A, F)
    np.testing.assert_allclose(pred["stiffness_nm_per_deg_u_inputs"],
                               10 * np.abs(refit.stiffness_nm_per_deg(A, F) - mu.map.stiffness_nm_per_deg(A, F)),
                               rtol=0.02)
    np.testing.assert_allclose(pred["damping_ratio_u_inputs"][1:3],
                               10 * np.abs(refit.damping_ratio(A, F) - mu.map.damping_ratio(A, F))[1:3], rtol=0.05)


def test_with_repeats_the_fits_share_shrinks_and_the_inertias_stays():
    """Eight repeats of every test: the fit's share of a prediction falls by about √8, the
    inertias' share (one J per fixture for all its repeats: correlated) does not fall at all."""
    given = override_uncertainty(None, [f"inertia_kgm2@{j}={0.01 * j}" for j in FIXTURES])
    one, eight = (map_uncertainty(_repeats(n), given).predict(A, F) for n in (1, 8))
    fit_ratio = eight["stiffness_nm_per_deg_u_fit"] / one["stiffness_nm_per_deg_u_fit"]
    assert np.all(fit_ratio < 0.55) and np.all(fit_ratio > 1 / 8)
    # the J share is the noise-free map's in both (10 %: the two maps are two noise draws' fits)
    exact = map_uncertainty(synthetic_table(0.0), given).predict(A, F)["stiffness_nm_per_deg_u_inputs"]
    for pred in (one, eight):
        np.testing.assert_allclose(pred["stiffness_nm_per_deg_u_inputs"], exact, rtol=0.1)
    assert (one["stiffness_nm_per_deg_dominant"] == "fit").all()
    assert eight["stiffness_nm_per_deg_dominant"].str.startswith("inertia_kgm2@").all()


def test_no_input_given_is_the_fits_share_alone_and_says_so():
    mu = map_uncertainty(synthetic_table(0.02))
    pred = mu.predict(A, F)
    assert (pred["stiffness_nm_per_deg_u_inputs"] == 0).all() and (pred["stiffness_nm_per_deg_dominant"] == "fit").all()
    assert mu.not_given == ("inertia_kgm2@0.1557", "inertia_kgm2@0.359", "inertia_kgm2@0.5233", "sample_rate_hz",
                            "laser_radius_m", "laser_calibration_rel")


def test_map_command_prints_writes_and_plots_the_expanded_uncertainties(tmp_path, capsys):
    import json

    from droptower.cli.main import main

    path = tmp_path / "results.csv"
    synthetic_table(0.02).to_csv(path, index=False)
    specs = ["--uncertainty", "inertia_kgm2@0.359=0.0036"]
    assert main(["map", str(path), *specs, "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)["uncertainty"]
    assert doc["coverage_factor"] == 2.0 and "inertia_kgm2@0.5233" in doc["not_given"]
    k5 = next(r for r in doc["coefficients"] if r["coefficient"] == "k5")
    assert k5["U95"] == pytest.approx(2 * np.hypot(k5["u_fit"], k5["u_inputs"]))
    out = tmp_path / "coefficients.csv"
    assert main(["map", str(path), *specs, "--out", str(out), "--plot", str(tmp_path / "figs")]) == 0
    assert "expanded uncertainties (k = 2" in capsys.readouterr().out
    assert {"u_fit", "u_inertia_kgm2@0.359", "U95", "dominant"} <= set(pd.read_csv(out).columns)
    assert (tmp_path / "figs" / "fig13_damping_map.png").is_file()


def test_map_json_keeps_the_input_uncertainties_it_was_computed_with(tmp_path):
    """map.json stores the rig's input uncertainties (validate reuses them); a malformed entry is
    a one-line error naming the file; an older file without them reads as none given."""
    import json

    from droptower.errors import DroptowerError
    from droptower.maps.mapfit import MapFit

    m = fit_map(synthetic_table(0.02))
    u = override_uncertainty(None, ["inertia_kgm2@0.359=0.00359", "sample_rate_hz=20:rectangular"])
    m.input_uncertainty = u.model_dump(exclude_none=True)
    back = MapFit.from_json(m.to_json(tmp_path / "map.json") and tmp_path / "map.json")
    assert type(u).model_validate(back.input_uncertainty) == u
    doc = json.loads((tmp_path / "map.json").read_text())
    doc["input_uncertainty"] = {"sample_rate_hz": {"value": -1}}
    (tmp_path / "bad.json").write_text(json.dumps(doc))
    with pytest.raises(DroptowerError, match="bad.json"):
        MapFit.from_json(tmp_path / "bad.json")
    del doc["input_uncertainty"]
    (tmp_path / "old.json").write_text(json.dumps(doc))
    assert MapFit.from_json(tmp_path / "old.json").input_uncertainty is None
