"""Filled rubber at large strain: the ``filled_rubber`` family with its large-strain network
(docs/theory.md#large-strain-network) against rubber it was not built from.

- A real high-damping rubber bearing (tests/data/hdrb: the cyclic shear test behind Gallardo et
  al. 2023, MIT): fitted to the first three amplitude blocks, the whole record predicted from
  rest, the families ranked by that prediction (compare-models' hold-out rule).
- A published filled-rubber law implemented here, independently of the package: the
  high-damping-rubber model of Gallardo, de la Llera, Restrepo & Chen (2023), Engineering
  Structures 289, 116234, with the parameters the authors publish for that bearing
  (JAGallardo1992/HDRB_model, 2D_model/Data/Parameters.txt, MIT): a hyperelastic spring
  a1 u - a2 u^3 + a3 u^5 whose terms soften with the largest strain seen and the travel
  (Mullins, scragging), in parallel with a Bouc-Wen element with temporary hardening. Run as
  servo records in mm and kN, fitted on four amplitude blocks from rest, predicted on an unseen
  larger amplitude and a decaying sine.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from droptower.identify import compare_models, identify, segments_from_files
from droptower.identify.ranking import HOLDOUT_RULE, by_holdout_error
from droptower.identify.families import FilledRubberFamily
from droptower.identify.data import DataScale

DATA = Path(__file__).parent / "data" / "hdrb" / "test_hdrb.csv.gz"
CM, TONF = 1e-2, 9806.65  # m per cm, N per tonf
#: Every 4th sample of the record (6593 of 26 372; ~240 per cycle at the smallest amplitude):
#: the same figures as the whole record to 0.4 % nRMSE (measured: 3.65 % against 3.21 %), a
#: quarter of the time.
DECIMATE = 4
#: The record has no time vector: a sample interval (s) of the decimated record (~0.4 Hz cycles).
DT_S = 0.01
#: The bearing's rubber height (cm), from the record (``h``).
HEIGHT_CM = 15.6


def bearing() -> tuple[np.ndarray, np.ndarray, list[int]]:
    """(displacement m, force N, the sample indices where the 7.6, 15.2 and 23 cm blocks start:
    the zero crossing before each block's first excursion beyond 70 % of its amplitude)."""
    table = np.loadtxt(DATA, delimiter=",", skiprows=1)[::DECIMATE]
    d, f = table[:, 0] * CM, table[:, 1] * TONF
    cuts = []
    for amplitude_cm in (7.6, 15.2, 23.0):
        first = int(np.argmax(np.abs(d) > 0.7 * amplitude_cm * CM))
        crossings = np.flatnonzero(np.sign(d[1:first]) != np.sign(d[:first - 1]))
        cuts.append(int(crossings[-1]) + 1)
    return d, f, cuts


def test_the_shipped_record_is_the_published_test():
    """The record's blocks as the paper describes them: 7 cycles each at 3.8, 7.6, 15.2 cm, then 6
    at 23 cm, from rest; its peak force (tonf) as the authors plot it (-45 to 45 tonf axes)."""
    d, f, cuts = bearing()
    blocks = np.split(d, cuts)
    assert [round(float(np.max(np.abs(b))) / CM, 1) for b in blocks] == [3.8, 7.6, 15.2, 23.0]
    reversals = [int(np.sum(np.diff(np.sign(np.diff(b[np.abs(b) > 0.5 * np.max(np.abs(b))]))) != 0)) for b in blocks]
    assert d[0] == 0.0 and 30 < np.max(np.abs(f)) / TONF < 45 and len(d) == math.ceil(26372 / DECIMATE)
    assert all(r >= 10 for r in reversals)  # several cycles per block


@pytest.fixture(scope="module", autouse=True)
def fits(request):
    """One fit per distinct call in this module (tests/shared_fits.py): the bearing's
    filled_rubber fit on its published record is one identification for the library's
    compare_models and for both commands."""
    from shared_fits import share_fits

    with share_fits(request.module, keep=__name__) as cache:
        yield cache


@pytest.fixture(scope="module")
def published(tmp_path_factory) -> tuple[Path, Path]:
    """The bearing's record as published (cm, tonf, no time; every 4th sample): its first
    three blocks and the whole, as two CSV files."""
    d, f, cuts = bearing()
    rows = np.column_stack([d / CM, f / TONF])
    folder = tmp_path_factory.mktemp("hdrb")
    return _published_csv(folder / "blocks.csv", rows[:cuts[2]]), _published_csv(folder / "whole.csv", rows)


@pytest.mark.slow
def test_bearing_predicted_from_its_first_three_blocks(published):
    """Fitted to the 3.8, 7.6 and 15.2 cm blocks, the whole record predicted from rest (the 23 cm
    block unseen): filled_rubber within 4 % nRMSE and better than every other family, and
    compare-models ranks it first by that prediction (measured: filled_rubber 2.05 % with the
    network's sided scragging, travel softening and reversal-set slips; 3.21 % when the
    network was built, 3.66 % re-measured on 2026-11-28 before those parts (3.39 % from the record
    written to CSV and read back: neighbouring minima by the last digits), masing 5.56 %, elastoslide 5.88 %,
    pfeffer 11.37 %; without the large-strain network filled_rubber was 6.78 %). The record is
    read as published (:func:`published`, in SI to the last digits the CSV keeps), the data the
    command-line test reads: the module's fits are shared, so the commands' filled_rubber fit is
    this one (measured on the CSV: filled_rubber 2.05 %, as from the arrays)."""
    blocks, whole = published
    fit = segments_from_files([blocks], sample_interval_s=DT_S)
    cmp = compare_models(fit, ["filled_rubber", "elastoslide", "masing", "pfeffer"],
                         holdout=segments_from_files([whole], sample_interval_s=DT_S), budget_s=None, total_budget_s=None)
    table = cmp.ranking.set_index("family")
    assert fit[0].units == "translational" and fit[0].dt_s == pytest.approx(DT_S, rel=1e-12)
    assert cmp.rule == HOLDOUT_RULE and cmp.best == "filled_rubber"
    assert list(cmp.ranking["family"]) == list(table["holdout_nrmse_percent"].sort_values().index)
    assert table.loc["filled_rubber", "holdout_nrmse_percent"] <= 4.0
    assert (table.drop("filled_rubber")["holdout_nrmse_percent"] > table.loc["filled_rubber", "holdout_nrmse_percent"]).all()


# ------------------------------------------------------------------ the published law
#: Gallardo et al. (2023)'s parameters of the bearing (Parameters.txt; cm, tonf, strains)
GALLARDO = dict(a1=44.1701915951363, a2=177.893643206245, a3=335.644706867365, fs1=0.628152583901373,
                ps1=0.635767087928480, fs2=23.2729155927115, ps2=0.305853049942929, fs3=4.00449976506282,
                ps3=0.388627887833079, fm=0.149541836425437, pm=0.504901052439698, uy=0.0177277301884489,
                fy=3.13037897682746, beta=0.9, n=0.388627887833079, fmax=0.211999802412063, pphi=0.0117472822372184)


def _sign(v: float) -> float:
    return 0.0 if v == 0.0 else math.copysign(1.0, v)


def gallardo_force_tonf(x_cm: np.ndarray, h_cm: float = HEIGHT_CM, p: dict[str, float] = GALLARDO) -> np.ndarray:
    """Force (tonf) of the Gallardo et al. (2023) model under the displacement history ``x_cm`` (cm)
    from rest, sample by sample: F = F_hyp + fy z.

    F_hyp = ks1 km a1 u - ks2 a2 u^3 + ks3 a3 u^5 (u = x / h): ks1 = exp(-fs1 g^ps1),
    ks2 = ks1 exp(-fs2 g^ps2), ks3 = ks1 exp(-fs3 g^ps3), g the Mullins strain of the current side
    (it grows by du / 2 on loading and 4 |du| on unloading, capped by the largest strain of that side),
    km = exp(-fm c^pm), c the side's accumulated unloading strain (scragging). z: Bouc-Wen,
    dz = (k / fy) du (1 - |z|^n (B sgn(du z) + 1 - B - phi sgn(du) (sgn(z) + sgn(du)))), k = fy / uy,
    integrated by the authors' fixed-point midpoint iteration; phi = fmax (1 - exp(-pphi |u_i / uy|))
    at each sign change of z, u_i the excursion at the last reversal.
    """
    k, g0 = p["fy"] / p["uy"], 1.0 - p["beta"]
    gp = gn = cp = cn = mp = mn = 0.0
    z = phi = u_rev = du_last = x_last = 0.0
    uy = p["uy"]
    out = np.empty(len(x_cm))
    for i, x in enumerate(np.asarray(x_cm, float)):
        dx = x - x_last
        if x >= 0.0:
            c = cp
            if dx >= 0.0:
                mp = max(mp, x / h_cm)
                g = min(gp + dx / (2.0 * h_cm), mp)
            else:
                mp = max(mp, x_last / h_cm)
                g = min(gp - 4.0 * dx / h_cm, mp)
                c -= dx / h_cm
            gp, cp = g, c
        else:
            c = cn
            if dx < 0.0:
                mn = max(mn, -x / h_cm)
                g = min(mn, gn - dx / (2.0 * h_cm))
            else:
                mn = max(mn, x_last / h_cm)
                g = min(mn, gn + 4.0 * dx / h_cm)
                c += dx / h_cm
            gn, cn = g, c
        ks1 = math.exp(-p["fs1"] * g ** p["ps1"])
        ks2 = ks1 * math.exp(-p["fs2"] * g ** p["ps2"])
        ks3 = ks1 * math.exp(-p["fs3"] * g ** p["ps3"])
        km = math.exp(-p["fm"] * c ** p["pm"])
        u, du = x / h_cm, dx / h_cm
        hyper = ks1 * km * p["a1"] * u - ks2 * p["a2"] * u ** 3 + ks3 * p["a3"] * u ** 5
        z0, trial, mid = z, z, z
        for it in range(11):
            dz = k / p["fy"] * du * (1.0 - abs(mid) ** p["n"] * (p["beta"] * _sign(du * mid) + g0
                                                              - phi * _sign(du) * (_sign(mid) + _sign(du))))
            new = z0 + dz
            if abs(new - trial) < 1e-7:
                break
            trial, mid = new, z0 + 0.5 * dz
            if it >= 9:
                mid = z0
        z = new
        if abs(_sign(du) - _sign(du_last)) == 2.0:
            u_rev = abs(u - uy - du)
        if abs(_sign(z) - _sign(z0)) == 2.0:
            phi = p["fmax"] * (1.0 - math.exp(-p["pphi"] * abs(u_rev / uy)))
        du_last, x_last = du, x
        out[i] = hyper + p["fy"] * z
    return out


def test_the_law_reproduces_the_authors_fit_of_the_bearing():
    """Implemented from the paper's equations, the law with the authors' parameters follows the
    shipped record to 1.92 % nRMSE, the figure the authors' own code (URB.py) gives on it
    (1.9233 %): the two implementations agree."""
    table = np.loadtxt(DATA, delimiter=",", skiprows=1)
    force = gallardo_force_tonf(table[:, 0])
    nrmse = float(np.sqrt(np.mean((force - table[:, 1]) ** 2)) / np.max(np.abs(table[:, 1])))
    assert nrmse == pytest.approx(0.019233, abs=2e-5)


#: Samples per cycle and the sample interval (s) of the law's servo records (0.1 Hz: quasi-static)
PER_CYCLE, LAW_DT_S = 200, 0.05
#: White noise of the records' force, as a fraction of its peak (a servo rig's load cell on a bearing)
LAW_NOISE = 0.01


def _law_records(tmp_path: Path) -> tuple[Path, Path, dict[str, slice]]:
    """The law's servo records as a lab exports them (``time [s]``, ``displacement [mm]``,
    ``force [kN]``): the fitting record, 4 cycles each at shear strains 0.25, 0.5, 1.0 and 1.5
    from rest; the prediction record, the same history followed by 4 cycles at an unseen 1.75
    and a sine from 1.5 decaying over 8 cycles (time constant 3 cycles). Noise seeded."""
    def block(strain: float, cycles: int) -> np.ndarray:
        return strain * HEIGHT_CM * np.sin(2 * np.pi * np.arange(cycles * PER_CYCLE) / PER_CYCLE)

    fit_cm = np.concatenate([block(s, 4) for s in (0.25, 0.5, 1.0, 1.5)])
    cycles = np.arange(8 * PER_CYCLE) / PER_CYCLE
    decay_cm = 1.5 * HEIGHT_CM * np.exp(-cycles / 3.0) * np.sin(2 * np.pi * cycles)
    x_cm = np.concatenate([fit_cm, block(1.75, 4), decay_cm])
    force_kn = gallardo_force_tonf(x_cm) * TONF / 1e3
    force_kn = force_kn + np.random.default_rng(42).normal(0.0, LAW_NOISE * np.max(np.abs(force_kn)), force_kn.size)
    paths = []
    for name, n in (("law_fit.csv", fit_cm.size), ("law_prediction.csv", x_cm.size)):
        path = tmp_path / name
        np.savetxt(path, np.column_stack([np.arange(n) * LAW_DT_S, 10.0 * x_cm[:n], force_kn[:n]]), delimiter=",",
                   header="time [s],displacement [mm],force [kN]", comments="", fmt="%.10g")
        paths.append(path)
    n_fit, n_big = fit_cm.size, fit_cm.size + 4 * PER_CYCLE
    return paths[0], paths[1], {"fitted blocks": slice(0, n_fit), "unseen amplitude": slice(n_fit, n_big),
                                "decaying sine": slice(n_big, x_cm.size)}


@pytest.mark.slow
def test_published_law_predicted_from_four_blocks(tmp_path):
    """filled_rubber fitted to the law's four blocks (records in mm and kN) predicts the unseen
    amplitude and the decaying sine better than the simpler families, with a verdict that is not
    poor, within the issue's 2 %. Measured on this tree: filled_rubber fit 1.32 %, prediction
    1.72 % (fitted blocks 1.30 %, unseen 1.75 strain 2.13 %, decaying sine 2.17 %; good fit);
    masing 8.0 %, elastoslide 8.0 %. Before the network's sided scragging, travel softening and
    reversal-set slips and the held scragging limit: fit 1.89 %, prediction 2.63 %
    (docs/theory.md#large-strain-network)."""
    fit_path, prediction_path, parts = _law_records(tmp_path)
    fit, prediction = segments_from_files([fit_path]), segments_from_files([prediction_path])
    assert fit[0].units == "translational"
    rubber = identify("filled_rubber", fit, holdout=prediction)
    assert not rubber.verdict.poor
    assert rubber.fit_error.nrmse < 0.022 and rubber.holdout_error.nrmse <= 0.02
    for kind in ("masing", "elastoslide"):
        assert identify(kind, fit, holdout=prediction).holdout_error.nrmse > 2 * rubber.holdout_error.nrmse


# ------------------------------------------------------------------ ranking by the hold-out
def test_the_hold_out_ranks_a_family_that_fits_better_but_predicts_worse_below():
    """The richer family fits better (BIC first) but predicts worse: ranked by the hold-out it
    comes second; two hold-out errors within the tie go to the family with fewer parameters."""
    import pandas as pd

    table = pd.DataFrame({"family": ["rich", "plain", "lean", "stuck"], "n_parameters": [24, 8, 5, 3],
                          "holdout_nrmse_percent": [6.0, 5.0, 5.05, 1.0], "bic": [10.0, 50.0, 60.0, 0.0],
                          "converged": [True, True, True, False]})
    ranked = by_holdout_error(table)
    assert list(ranked["family"]) == ["lean", "plain", "rich", "stuck"] and list(ranked.index) == [1, 2, 3, 4]


def test_the_large_strain_network_is_off_for_drop_tests_and_free_to_vanish():
    """The family as a drop-test fit builds it (option large_strain None) has today's 13
    parameters and no large-strain element; with the network on, every gain's lower bound is 0
    and at 0 the element is a linear spring (its stiffness also 0: nothing)."""
    scale = DataScale(0.05, 0.05, 500.0, 1e4, 1.0, 20.0)
    plain = FilledRubberFamily(scale)
    assert len(plain.parameters) == 13 and "large_strain_network" not in [e["kind"] for e in plain.elements(plain.guess())]
    rich = plain.with_large_strain()
    extra = {p.name: p for p in rich.parameters[13:]}
    assert all(extra[n].lower == 0.0 for n in ("ks_nm_per_rad", "ks_hardening_nm_per_rad", "kn_nm_per_rad",
                                               "network_hardening", "scragging", "travel_softening",
                                               "slip_hardening"))
    kinds = [e["kind"] for e in rich.elements(rich.guess())]
    assert "large_strain_network" in kinds and "variable_maxwell" not in kinds
    # the travel softening and the slip hardening at 0 and the sides shared: the network as it was
    shared = FilledRubberFamily(scale, {"large_strain": True, "large_strain_sides": False})
    v = shared.guess()
    v[[shared.names.index(n) for n in ("travel_softening", "slip_hardening")]] = 0.0
    element = next(e for e in shared.elements(v) if e["kind"] == "large_strain_network")
    assert element["travel_softening"] == 0.0 and element["slip_hardening"] == 0.0 and not element["damage_sides"]
    assert rich.elements(rich.guess())[-1]["damage_sides"]


# ------------------------------------------------------------------ the record on the command line
def _published_csv(path: Path, rows: np.ndarray) -> Path:
    """``rows`` (cm, tonf) written as the record is published: displacement and force, no time."""
    np.savetxt(path, rows, delimiter=",", header="displacement [cm],force [tonf]", comments="", fmt="%.8g")
    return path


def _cli(capsys, argv: list[str]) -> tuple[int, str, str]:
    from droptower.cli.main import main

    code = main(argv)
    out, err = capsys.readouterr()
    assert "Traceback" not in err and "internal error" not in err, err
    return code, out, err


def test_a_record_without_time_is_read_with_its_sample_interval(tmp_path, capsys):
    """The published record (cm, tonf, no time vector) read for identification: the time is
    uniform at dt, the force 9806.65 N per tonf, the displacement 0.01 m per cm, exactly; without
    a time base, with two, or with the drop-test route, a one-line error naming the file or the flags."""
    from droptower.errors import DroptowerError
    from droptower.identify.data import segments_from_files

    rows = np.loadtxt(DATA, delimiter=",", skiprows=1)[:2000]
    path = _published_csv(tmp_path / "bearing.csv", rows)
    written = np.loadtxt(path, delimiter=",", skiprows=1)
    for kw in ({"sample_interval_s": DT_S}, {"sample_rate_hz": 1.0 / DT_S}):
        (seg,) = segments_from_files([path], **kw)
        assert seg.units == "translational" and seg.lead_in == 0 and seg.dt_s == pytest.approx(DT_S, rel=1e-12)
        np.testing.assert_allclose(seg.angle_rad, written[:, 0] * CM, rtol=1e-15)
        np.testing.assert_allclose(seg.torque_nm, written[:, 1] * TONF, rtol=1e-15)
    with pytest.raises(DroptowerError, match=r"bearing\.csv: no time channel; give `sample_rate_hz` or `sample_interval_s`"):
        segments_from_files([path])
    with pytest.raises(DroptowerError, match="not both"):
        segments_from_files([path], sample_rate_hz=100.0, sample_interval_s=DT_S)
    for command in (["identify", "--family", "filled_rubber"], ["compare-models"]):
        code, _, err = _cli(capsys, command + [str(path)])
        assert code == 2 and "bearing.csv" in err and "--sample-rate-hz or --sample-interval-s" in err, err
        code, _, err = _cli(capsys, command + [str(path), "--sample-interval-s", "0.01", "--sample-rate-hz", "100"])
        assert code == 2 and "--sample-rate-hz or --sample-interval-s, not both" in err, err
        code, _, err = _cli(capsys, command + [str(tmp_path), "--from-drop-tests", "--sample-interval-s", "0.01"])
        assert code == 2 and "--sample-interval-s gives the time base of servo records" in err, err


@pytest.mark.slow
def test_the_published_record_through_identify_and_compare_models_on_the_command_line(published, fits, tmp_path, capsys):
    """The bearing's record as published (displacement in cm, force in tonf, no time vector; its
    first three blocks to fit, the whole as the hold-out, every 4th sample) through
    ``droptower identify --family filled_rubber --sample-interval-s`` and ``compare-models``: read
    in SI (the largest force 39.8 tonf = 390 kN), fitted and the whole predicted from rest within
    the issue's 4 % (measured: fit 2.09 %, hold-out 3.39 %; 4 s each), ranked by the hold-out. The
    verdict on real data is "poor fit" (the error is 26 times the record's noise floor, which a
    bearing's 8-digit record makes tiny): exit 3, unless --accept-poor. The two commands share
    the one fit (tests/shared_fits.py: keyed by the records as each command read them, so a
    command that read them otherwise would fit anew and be checked on its own), and with it
    the library's in :func:`test_bearing_predicted_from_its_first_three_blocks` where that ran
    first in this process (the same files read the same way)."""
    d, f, cuts = bearing()
    blocks, whole = published
    records = [str(blocks), "--sample-interval-s", str(DT_S), "--holdout", str(whole), "--json"]
    calls, fitted = fits.calls, fits.fits
    code, out, err = _cli(capsys, ["compare-models", *records, "--families", "filled_rubber"])
    (row,) = json.loads(out)["ranking"]
    assert code == 3 and "poor fit" in err and row["family"] == "filled_rubber" and row["holdout_nrmse_percent"] <= 4.0
    code, out, _ = _cli(capsys, ["identify", *records, "--family", "filled_rubber", "--accept-poor",
                                 "--out", str(tmp_path / "bearing.toml")])
    # both commands read the same records: one key, fitted at most once
    assert fits.calls == calls + 2 and fits.keys[-1] == fits.keys[-2] and fits.fits <= fitted + 1
    report = json.loads(out)
    assert code == 0 and report["units"] == "translational" and (tmp_path / "bearing.toml").exists()
    assert report["holdout_error"]["n_samples"] == d.size and report["fit_error"]["n_samples"] == cuts[2]
    assert report["holdout_error"]["max_force_n"] == pytest.approx(np.max(np.abs(f)), rel=1e-7)
    assert report["holdout_error"]["nrmse_percent"] <= 4.0 and report["fit_error"]["nrmse_percent"] < report["holdout_error"]["nrmse_percent"]
    assert report["holdout_error"]["nrmse_percent"] == pytest.approx(row["holdout_nrmse_percent"], rel=1e-6)
