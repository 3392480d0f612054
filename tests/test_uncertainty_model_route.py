"""The rig's inputs in the model route's expanded uncertainties (droptower.uncertainty.route):
the identification's shift for each input against closed forms of a Kelvin-Voigt coupling (J
scales every identified stiffness and leaves the loss factor; the clock scales k by its square,
c by itself), the shifted sets through model_map.json, and the coverage machinery of
benchmarks/bench_uncertainty_route.py on a few campaigns (tests/coverage_campaigns.py)."""
import functools
import math

import numpy as np
import pytest

from coverage_campaigns import FIXTURES, LASER_M, LEVER_M, ROUTE_STATED, route_campaign
from droptower.errors import DroptowerError
from droptower.rig.uncertainty import FixtureUncertainty, InputUncertainty, RigUncertainty

K, C = 18_000.0, 15.0


@functools.lru_cache(maxsize=None)
def _identified(torque_weight: float = 0.5, force: bool = True):
    """A noisy Kelvin-Voigt campaign (one drop per fixture) identified with the template family;
    without ``force`` the rate after the impact comes from the angle's slope."""
    import tempfile

    from coverage_campaigns import FS, SERVO_HZ, _template  # noqa: F401
    from droptower.extract import SyntheticDrop
    from droptower.identify.dropfit import DropFitSettings
    from droptower.identify.droplogs import ReadSettings, decay_from_signals
    from droptower.identify.drop_campaign import DropCampaign, identify_from_drop_tests
    from droptower.io.signals import DropSignals

    decays = []
    for i, j in enumerate(FIXTURES):
        delta = C / (2 * j)
        omega = math.sqrt(K / j - delta ** 2)
        d = 0.5 * (math.exp(4 * math.pi * delta / omega) - 1)
        drop = SyntheticDrop(inertia_kgm2=j, stiffness_nm_per_rad=K, damping_ratio=d, lever_length_m=LEVER_M,
                             amplitude_deg=1.5, sample_rate_hz=FS, duration_s=0.06, pretrigger_s=0.01, seed=i)
        t, ch = drop.channels()
        signals = DropSignals(t - t[0], ch["angle_rad"], ch["torque_nm"], ch["impact_force_n"] if force else None,
                              metadata={"inertia_kgm2": j, "lever_length_m": LEVER_M})
        decays.append(decay_from_signals(signals, ReadSettings(), f"drop_{i}"))
    folder = tempfile.mkdtemp()
    campaign = DropCampaign(decays, [], DropFitSettings(holdout_fraction=0.0, conditioning=None,
                                                        torque_weight=torque_weight),
                            {"template": _template(folder)}, ReadSettings())
    return identify_from_drop_tests(campaign, "template"), decays, campaign.settings


def _shares(uncertainty, torque_weight: float = 0.5, force: bool = True):
    from droptower.compare.model_map import model_map_from_identification

    ident, decays, settings = _identified(torque_weight, force)
    mm = model_map_from_identification(ident, decays, settings, uncertainty=uncertainty, lever_length_m=LEVER_M,
                                       laser_radius_m=LASER_M)
    return mm, mm.input_shares([1.5], [10.0])


def test_inertia_scales_the_stiffness_and_leaves_the_loss_factor():
    """Angle only, the rate after the impact from its slope: every fixture's J moved by 1 %
    together moves K' by 1 % (J φ'' + c φ' + k φ = 0 holds with J, c, k scaled alike), η = c·ω_s/k
    not at all; each fixture alone moves K' by its share (the sum: superposition)."""
    u = RigUncertainty(inertias_kgm2=[FixtureUncertainty(nominal=j, value=0.01 * j) for j in FIXTURES])
    mm, shares = _shares(u, torque_weight=0.0, force=False)
    row = mm.evaluate([1.5], [10.0]).iloc[0]
    dk = sum(v[0] for v in shares["storage_stiffness_nm_per_deg"].values())
    assert dk / row["storage_stiffness_nm_per_deg"] == pytest.approx(0.01, rel=0.02)
    assert abs(sum(v[0] for v in shares["loss_factor"].values())) / row["loss_factor"] < 2e-3
    assert all(v[0] > 0 for v in shares["storage_stiffness_nm_per_deg"].values())


def test_the_flange_holds_part_of_the_stiffness_against_the_inertia():
    """With the torque in the fit the flange reads k·φ + c·φ' whatever J is: a J error moves K'
    by less than u_J/J (what the closed form J·ω² alone would say), and the flange's own
    calibration moves it (the angle-only fit does not see the flange at all)."""
    u = RigUncertainty(inertias_kgm2=[FixtureUncertainty(nominal=j, value=0.01 * j) for j in FIXTURES],
                       torque_calibration_rel=InputUncertainty(value=0.01))
    mm, shares = _shares(u)
    k = shares["storage_stiffness_nm_per_deg"]
    k0 = mm.evaluate([1.5], [10.0])["storage_stiffness_nm_per_deg"].iloc[0]
    j_share = sum(v[0] for key, v in k.items() if key.startswith("inertia")) / k0
    assert 0.005 < j_share < 0.0099
    assert k["torque_calibration_rel"][0] < 0  # the flange reads high: the stiffness it implies is lower
    _, angle_only = _shares(u, torque_weight=0.0)
    assert angle_only["storage_stiffness_nm_per_deg"]["torque_calibration_rel"][0] == 0.0


def test_the_clock_scales_stiffness_by_its_square_and_the_loss_factor_inversely():
    """A log labelled at f_s whose clock ran at f_s(1 + ε) (angle only, the rate from its slope):
    k ∝ f², c ∝ f, η(ω_s) = c·ω_s/k ∝ 1/f."""
    eps = 0.002
    from coverage_campaigns import FS

    mm, shares = _shares(RigUncertainty(sample_rate_hz=InputUncertainty(value=eps * FS)), 0.0, False)
    row = mm.evaluate([1.5], [10.0]).iloc[0]
    assert shares["storage_stiffness_nm_per_deg"]["sample_rate_hz"][0] / row["storage_stiffness_nm_per_deg"] == \
        pytest.approx((1 + eps) ** 2 - 1, rel=0.03)
    # the lever's integration step moves with the clock too: its bias on η (~1e-4, relative) is the margin
    assert shares["loss_factor"]["sample_rate_hz"][0] / row["loss_factor"] == pytest.approx(1 / (1 + eps) - 1, abs=2e-4)


def test_the_shifted_sets_travel_through_model_map_json(tmp_path):
    from droptower.compare.model_map import ModelMap

    mm, _ = _shares(ROUTE_STATED)
    assert set(mm.input_sets) == {*(f"inertia_kgm2@{j:g}" for j in FIXTURES), "lever_length_m", "laser_radius_m",
                                  "laser_calibration_rel", "torque_calibration_rel", "force_calibration_rel",
                                  "sample_rate_hz"}
    mm.to_json(tmp_path / "model_map.json")
    back = ModelMap.from_json(tmp_path / "model_map.json")
    assert back.input_uncertainty == mm.input_uncertainty
    assert RigUncertainty.model_validate(back.input_uncertainty) == ROUTE_STATED
    a, b = mm.evaluate([1.0, 2.0], [5.0, 10.0]), back.evaluate([1.0, 2.0], [5.0, 10.0])
    np.testing.assert_allclose(a["storage_stiffness_nm_per_deg_U95"], b["storage_stiffness_nm_per_deg_U95"], rtol=1e-12)
    # U95 = 2·√(u_fit² + u_inputs²), k = 2
    np.testing.assert_allclose(a["loss_factor_U95"], 2 * np.hypot(a["loss_factor_std"], a["loss_factor_u_inputs"]))


def test_a_given_uncertainty_needs_its_nominal_value():
    from droptower.compare.model_map import model_map_from_identification

    ident, decays, settings = _identified()
    with pytest.raises(DroptowerError, match="laser_radius_m"):
        model_map_from_identification(ident, decays, settings, bands=False,
                                      uncertainty=RigUncertainty(laser_radius_m=InputUncertainty(value=1e-3)))


def test_route_campaigns_machinery():
    """Four campaigns of the coverage benchmark (one drop per fixture): the identification
    converges, the truth is drawn and recovered within the intervals with the inputs; the fit's
    bands alone are narrower (the benchmark counts how often they miss: benchmarks/results/uncertainty_route.json)."""
    rows = [route_campaign(seed, drops_per_fixture=1) for seed in range(4)]
    for r in rows:
        assert r["converged"] == 1.0
        for q in ("k", "eta"):
            assert r[f"{q}_U95_fit"] < r[f"{q}_U95"]
            assert abs(r[q] / r[f"{q}_true"] - 1) < 0.05
    assert sum(abs(r["k"] - r["k_true"]) <= r["k_U95"] for r in rows) >= 3


@pytest.fixture(scope="session")  # kept when worksteal splits this file: a second block reuses it
def kv_campaign(tmp_path_factory):
    """`campaign --uncertainty` on a Kelvin-Voigt coupling: three drops, one per fixture."""
    from droptower.cli.main import main
    from droptower.rheology import coupling_to_toml, parse_coupling

    root = tmp_path_factory.mktemp("kv_campaign")
    (root / "kv.toml").write_text(coupling_to_toml(parse_coupling(
        {"element": [{"kind": "spring", "stiffness": K}, {"kind": "dashpot", "damping": C}]})))
    (root / "plan.toml").write_text('name = "kv"\nbase_seed = 3\nrepeats = 1\nheights_m = [0.5]\npreloads_nm = [0.0]\n'
                                    + "".join(f'[[group]]\nname = "J{j}"\ninertia_kgm2 = {j}\ndrop_mass_kg = 2.0\n'
                                              for j in FIXTURES))
    code = main(["campaign", "--doe", str(root / "plan.toml"), "--coupling", str(root / "kv.toml"), "--out",
                 str(root / "camp"), "--workers", "1", "--duration-s", "0.1", "--uncertainty",
                 "inertia_kgm2@0.359=0.00359", "--uncertainty", "sample_rate_hz=4"])
    assert code == 0
    return root


@pytest.mark.slow  # a campaign and an identification (~10 s on a loaded machine)
def test_campaign_and_identify_state_the_inputs(kv_campaign, capsys):
    """campaign --uncertainty writes the per-drop columns (the fixture without a stated J names it
    as not given); identify --from-drop-tests --uncertainty gives each parameter's budget, J the
    stiffness's dominant input (1 % against a fit of ~0.1 %)."""
    import json

    import pandas as pd

    from droptower.cli.main import main

    table = pd.read_csv(kv_campaign / "camp" / "results_uncertainty.csv")
    assert len(table) == 3 and table["stiffness_nm_per_deg_U95"].notna().all()
    j = table.set_index("inertia_kgm2")
    assert "inertia_kgm2" in j.loc[0.1557, "uncertainty_not_given"]
    assert "inertia_kgm2" not in j.loc[0.359, "uncertainty_not_given"]
    capsys.readouterr()
    code = main(["identify", "--from-drop-tests", str(kv_campaign / "camp"), "--family", "template", "--template",
                 str(kv_campaign / "kv.toml"), "--holdout-fraction", "0", "--json",
                 *[a for f in FIXTURES for a in ("--uncertainty", f"inertia_kgm2@{f}={0.01 * f}")]])
    assert code == 0
    rows = {r["parameter"]: r for r in json.loads(capsys.readouterr().out)["uncertainty"]["parameters"]}
    k = rows["e1_spring_stiffness_factor"]
    assert k["dominant"].startswith("inertia_kgm2@") and k["U95"] == pytest.approx(2 * k["u_c"])
    assert 0.003 < k["u_inputs"] / k["value"] < 0.01  # each fixture's 1 %, on a third of the drops each


def test_uncertainty_on_identify_needs_drop_tests(capsys):
    from droptower.cli.main import main

    code = main(["identify", "x.csv", "--family", "zerodim6", "--uncertainty", "sample_rate_hz=4"])
    _, err = capsys.readouterr()
    assert code == 2 and "--from-drop-tests" in err and "Traceback" not in err
