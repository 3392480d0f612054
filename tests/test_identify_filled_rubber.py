"""The generic filled-elastomer family ``filled_rubber`` (docs/theory.md#filled-rubber): its closed
form against the servo bench, its fixed structure for any band, its first guess, seeded random
recovery from servo records and drop tests, the ranking, a translational case, and the commands
that enumerate it (design, compare-models, export-fmu)."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from droptower.cli.main import main
from droptower.identify import Identification, identify
from droptower.identify.data import DataScale
from droptower.identify.families import FAMILIES, FilledRubberFamily
from droptower.identify.report import ranking_table
from droptower.rheology import Coupling, parse_coupling
from droptower.servo import run_grid
from random_couplings import random_truth, servo_records

SCALE = DataScale(0.05, 0.05, 1200.0, 2.5e4, 5.0, 30.0)


def _random_values(fam: FilledRubberFamily, rng) -> np.ndarray:
    """A parameter set drawn inside the ranges a coupling of the drop tower has (not the bounds'
    extremes, where the network's yield angles leave any motion the bench runs)."""
    k = fam.scale.stiffness_nm_per_rad
    f_min = math.exp(rng.uniform(math.log(0.1), math.log(3.0)))
    return np.array([k * rng.uniform(0.2, 0.5), k * rng.uniform(0.0, 300.0), k * rng.uniform(0.3, 0.7),
                     rng.uniform(0.002, 0.01), rng.uniform(0.35, 0.7), rng.uniform(0.01, 0.05),
                     k * rng.uniform(0.02, 0.1), rng.uniform(0.3, 2.0), f_min, rng.uniform(2.0, 4.0),
                     k * rng.uniform(0.02, 0.2), k * rng.uniform(0.0, 100.0), 1.0 / (2 * math.pi * rng.uniform(3.0, 300.0))])


def test_the_family_is_registered_for_servo_records_and_drop_tests():
    from droptower.cli.identify_cmd import DROP_FAMILY_NAMES, FAMILY_NAMES
    from droptower.identify.dropfit import DROP_FAMILIES
    from droptower.identify.strategies import SEARCHABLE

    assert FAMILIES["filled_rubber"] is FilledRubberFamily
    assert {"filled_rubber"} <= set(DROP_FAMILIES) & set(DROP_FAMILY_NAMES) & set(FAMILY_NAMES) & set(SEARCHABLE)


@pytest.mark.parametrize("seed", range(3))
def test_closed_form_is_the_benchs_first_harmonic(seed):
    """The closed form the first guess fits (cubic spring's first harmonic, the network broken
    down to g_eq(A), the band's Prony series) against the core on the virtual bench, at random
    parameter sets: K' within 1.5 %, K'' within 4 % of |K*| (the closed form leaves out the
    network's recovery within the run-in and its centre's motion)."""
    fam = FilledRubberFamily(SCALE)
    v = _random_values(fam, np.random.default_rng(seed))
    amps, freqs = np.radians([0.3, 1.0, 3.0]), np.array([5.0, 30.0])
    grid = run_grid(fam.coupling(v), amps, freqs, sample_rate_hz=4096.0)
    bench = grid["storage_stiffness_nm_per_rad"].to_numpy() + 1j * grid["loss_stiffness_nm_per_rad"].to_numpy()
    closed = fam.harmonic_stiffness(v, grid["amplitude_rad"].to_numpy(), grid["frequency_hz"].to_numpy())
    np.testing.assert_allclose(closed.real, bench.real, rtol=0.015)
    np.testing.assert_allclose(closed.imag, bench.imag, atol=0.04 * float(np.max(np.abs(bench))))


@pytest.mark.parametrize("seed", range(3))
def test_stiffening_maxwell_closed_form_is_the_benchs_first_harmonic(seed):
    """The stiffening Maxwell branch's first-harmonic linearisation (the closed form's viscous
    part that grows with the amplitude) against the core on the virtual bench, at random
    springs, gains (up to a fivefold stiffening at 3 deg) and relaxation frequencies (3-300 Hz):
    K' and K'' within 2 % of |K*| (the linearisation leaves out the spring's higher harmonics)."""
    from droptower.identify.families.filled_rubber import stiffening_maxwell_stiffness

    rng = np.random.default_rng(700 + seed)
    k0 = 10 ** rng.uniform(3.0, 4.0)
    gain, damping = k0 * rng.uniform(10.0, 80.0), k0 / (2 * math.pi * 10 ** rng.uniform(math.log10(3.0), math.log10(300.0)))
    coupling = parse_coupling({"name": "stiffening_maxwell", "element": [
        {"kind": "variable_maxwell", "stiffness": k0, "stiffness_gain": gain, "damping": damping}]})
    grid = run_grid(coupling, np.radians([0.3, 1.0, 3.0]), np.array([5.0, 30.0]), sample_rate_hz=4096.0)
    bench = grid["storage_stiffness_nm_per_rad"].to_numpy() + 1j * grid["loss_stiffness_nm_per_rad"].to_numpy()
    closed = stiffening_maxwell_stiffness(k0, gain, damping, grid["amplitude_rad"].to_numpy(), grid["frequency_hz"].to_numpy())
    np.testing.assert_array_less(np.abs(closed.real - bench.real), 0.02 * np.abs(bench))
    np.testing.assert_array_less(np.abs(closed.imag - bench.imag), 0.02 * np.abs(bench))
    # the mechanism: at 30 Hz the loss factor changes with the amplitude as the spring stiffens
    eta = (closed.imag / closed.real)[grid["frequency_hz"].to_numpy() == 30.0]
    assert abs(eta[-1] / eta[0] - 1) > 0.05


@settings(max_examples=200, deadline=None, derandomize=True)
@given(st.floats(-2.0, 6.0), st.floats(-3.0, 4.0), st.floats(-3.0, 4.0), st.floats(-6.0, 0.0), st.floats(-3.0, 3.5))
def test_stiffening_maxwell_elongation_solves_its_equation(log_k0, log_gain_ratio, log_relaxation_hz, log_amp, log_f):
    """The branch's elongation amplitude E (Newton's method on a convex quartic) is the root of
    E = A omega c / |k(E) + i omega c| that a bracketing root finder gives, to 1e-12 relative, from
    springs of 0.01 to 1e6 N*m/rad, stiffening from 1e-3 to 1e4 times over a radian, relaxing at
    1e-3 to 1e4 Hz, at amplitudes of 1e-6 to 1 rad and 1e-3 to 3000 Hz."""
    from scipy.optimize import brentq

    from droptower.identify.families.filled_rubber import _ABS_SIN_HARMONIC, stiffening_maxwell_stiffness

    k0, amp, f = 10.0 ** log_k0, 10.0 ** log_amp, 10.0 ** log_f
    gain, damping = k0 * 10.0 ** log_gain_ratio, k0 / (2 * math.pi * 10.0 ** log_relaxation_hz)
    wc = 2 * math.pi * f * damping
    e = brentq(lambda x: x - amp * wc / abs(k0 + gain * _ABS_SIN_HARMONIC * x + 1j * wc), 0.0, amp,
               xtol=1e-300, rtol=4 * np.finfo(float).eps)
    k = k0 + gain * _ABS_SIN_HARMONIC * e
    got = stiffening_maxwell_stiffness(k0, gain, damping, np.array([amp]), np.array([f]))[0]
    assert abs(got - k * 1j * wc / (k + 1j * wc)) <= 1e-12 * abs(k * 1j * wc / (k + 1j * wc))


def _at_positions(fam: FilledRubberFamily, position) -> np.ndarray:
    """The parameter set at ``position`` (13 numbers in [0, 1]) along each optimised variable's bounds."""
    return np.array([p.to_value(p.to_z(p.lower) + u * (p.to_z(p.upper) - p.to_z(p.lower)))
                     for p, u in zip(fam.parameters, position)])


def _closed_form_of_the_specs(fam: FilledRubberFamily, v: np.ndarray, amp: np.ndarray, freq: np.ndarray) -> np.ndarray:
    """K* of parameter set ``v`` from the validated element specs' own methods
    (FillerNetwork.complex_stiffness, PowerLaw.complex_stiffness), the spring's first harmonic
    and the stiffening branch."""
    from droptower.identify.families.filled_rubber import stiffening_maxwell_stiffness
    from droptower.rheology.elements import FillerNetwork, PowerLaw

    _, network, matrix, *_ = fam.elements(v)
    return (v[0] + 0.75 * v[1] * amp ** 2 + FillerNetwork(**network).complex_stiffness(amp)
            + PowerLaw(**matrix).complex_stiffness(freq)
            + (stiffening_maxwell_stiffness(v[10], v[11], v[10] * v[12], amp, freq)
               if fam.options["stiffening_branch"] else 0.0))


@settings(max_examples=150, deadline=None, derandomize=True)
@given(st.lists(st.floats(0.0, 1.0), min_size=13, max_size=13), st.integers(2, 40), st.integers(2, 40),
       st.booleans(), st.lists(st.tuples(st.floats(-7.0, 0.5), st.floats(-2.0, 3.5)), min_size=1, max_size=12))
def test_closed_form_on_numbers_is_the_element_specs(position, n, terms, branch, readings):
    """The closed form evaluated on the numbers (the elements' pure functions, no spec built)
    equals, to rounding (1e-13 of |K*|), the validated element specs' own methods
    (FillerNetwork.complex_stiffness, PowerLaw.complex_stiffness) plus the spring's first
    harmonic and the stiffening branch, at random parameter sets anywhere in the bounds (each
    at a random position in its optimised variable), networks of 2-40 elements, bands of 2-40
    terms, random amplitudes (1e-7 to 3 rad) and frequencies (0.01 Hz to 3 kHz)."""
    fam = FilledRubberFamily(SCALE, {"n": n, "terms": terms, "stiffening_branch": branch})
    v = _at_positions(fam, position)
    amp, freq = 10.0 ** np.array(readings).T
    want = _closed_form_of_the_specs(fam, v, amp, freq)
    got = fam.harmonic_stiffness(v, amp, freq)
    assert got.shape == amp.shape
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-13 * float(np.max(np.abs(want))))


def test_closed_form_refuses_what_the_element_specs_refuse():
    """A parameter set an element spec refuses (a non-positive or non-finite field the closed
    form reads, a band of negative width) is refused by the closed form with a one-line error naming the
    field, as the first guess's fit expects of a start the element refuses."""
    from droptower.errors import DroptowerError

    fam = FilledRubberFamily(SCALE)
    for index, field in ((2, "stiffness"), (3, "critical_angle"), (6, "storage_stiffness"), (7, "loss_factor")):
        for bad in (0.0, -1.0, math.nan):
            v = fam.initial()
            v[index] = bad
            with pytest.raises(DroptowerError, match=f"field {field} of element"):
                fam.harmonic_stiffness(v, np.radians([1.0]), np.array([30.0]))
    v = fam.initial()
    v[9] = -1.0
    with pytest.raises(DroptowerError, match="(band_decades|max_frequency|terms_per_decade)"):
        fam.harmonic_stiffness(v, np.radians([1.0]), np.array([30.0]))


@settings(max_examples=60, deadline=None, derandomize=True)
@given(st.lists(st.tuples(st.lists(st.floats(0.0, 1.0), min_size=13, max_size=13), st.integers(0, 5)), min_size=1,
                max_size=6),
       st.integers(2, 40), st.integers(2, 40), st.booleans(),
       st.lists(st.tuples(st.floats(-7.0, 0.5), st.floats(-2.0, 3.5)), min_size=1, max_size=12))
def test_closed_form_of_a_batch_is_each_sets_own(sets, n, terms, branch, readings):
    """The closed form of M parameter sets at once (the first guess's Jacobian: one call for all
    its shifted points) equals, row by row, to rounding (1e-13 of |K*|), the single set's closed
    form and the validated element specs' own methods, at 1-6 random sets anywhere in the bounds,
    some sharing a power-law band (one call of the elements' closed forms per band), some not,
    networks of 2-40 elements, bands of 2-40 terms and random readings."""
    fam = FilledRubberFamily(SCALE, {"n": n, "terms": terms, "stiffening_branch": branch})
    rows = np.array([_at_positions(fam, position) for position, _ in sets])
    for r, (_, band_of) in enumerate(sets):
        rows[r, 8:10] = rows[band_of % (r + 1), 8:10]  # the band of an earlier set (or its own)
    amp, freq = 10.0 ** np.array(readings).T
    got = fam.harmonic_stiffness_rows(rows, amp, freq)
    assert got.shape == (len(rows), amp.size)
    for v, row in zip(rows, got):
        want = _closed_form_of_the_specs(fam, v, amp, freq)
        scale = 1e-13 * float(np.max(np.abs(want)))
        np.testing.assert_allclose(row, fam.harmonic_stiffness(v, amp, freq), rtol=0, atol=scale)
        np.testing.assert_allclose(row, want, rtol=0, atol=scale)


@pytest.mark.parametrize("shared_band", [True, False])
def test_a_refused_set_in_a_batch_is_refused_as_alone(shared_band):
    """A parameter set the element specs refuse (a non-positive or non-finite field, a band of
    negative width) among valid ones, first, inside or last in the batch: the batch's closed form
    raises the one-line error the set raises alone."""
    from droptower.errors import DroptowerError

    fam = FilledRubberFamily(SCALE)
    rng = np.random.default_rng(17)
    amp, freq = np.radians([0.3, 1.0, 2.0]), np.array([10.0, 30.0, 60.0])
    for index, bad in ((2, 0.0), (3, -1.0), (4, math.nan), (5, math.inf), (6, -2.0), (7, math.nan), (8, -1.0),
                       (9, -1.0), (9, math.nan)):
        good = np.array([_random_values(fam, rng) for _ in range(4)])
        if shared_band:
            good[:, 8:10] = good[0, 8:10]
        v = good[1].copy()
        v[index] = bad
        with pytest.raises(DroptowerError) as alone:
            fam.harmonic_stiffness(v, amp, freq)
        for position in (0, 2, 4):
            with pytest.raises(DroptowerError) as batch:
                fam.harmonic_stiffness_rows(np.insert(good, position, v, axis=0), amp, freq)
            assert str(batch.value) == str(alone.value)
            assert "\n" not in str(batch.value)


def test_first_guess_with_the_batched_jacobian_is_scipys_per_point_one(monkeypatch):
    """The first guess's forward-difference Jacobian evaluates its shifted points in one call of
    the batched closed form (least_squares' ``workers``); scipy's default, one call per point,
    gives the same guess (to 1e-10; the same steps and differences) on a seeded noisy case."""
    from scipy.optimize import least_squares

    import droptower.identify.families.filled_rubber as module

    fam = FilledRubberFamily(SCALE, {"stiffening_branch": False})
    rng = np.random.default_rng(23)
    truth = _random_values(fam, rng)
    a, f = (x.ravel() for x in np.meshgrid(np.radians([0.3, 1.0, 2.5]), [20.0, 45.0]))
    k_obs = fam.harmonic_stiffness(truth, a, f) * (1 + 0.01 * rng.standard_normal(a.size))
    x0 = fam.initial()
    x0[8:10] = truth[8:10]
    given = np.zeros(len(x0), bool)
    given[10:] = True  # the branch, off here
    sizes: list[int] = []
    rows_of = fam.harmonic_stiffness_rows
    monkeypatch.setattr(fam, "harmonic_stiffness_rows", lambda rows, *args: sizes.append(len(rows)) or rows_of(rows, *args))
    batched = fam.guess_from_readings(a, f, k_obs, x0, given)
    assert max(sizes) == 8 and sizes.count(8) > 13  # every Jacobian: its 8 shifted points at once
    monkeypatch.setattr(module, "least_squares", lambda *args, workers=None, **kw: least_squares(*args, **kw))
    sizes.clear()
    per_point = fam.guess_from_readings(a, f, k_obs, x0, given)
    assert max(sizes) == 1
    np.testing.assert_allclose(batched, per_point, rtol=1e-10, atol=0)
    misfit = [np.max(np.abs(fam.harmonic_stiffness(v, a, f) / k_obs - 1)) for v in (x0, batched)]
    assert misfit[1] < 0.03 < misfit[0]  # the guess moved from the start onto the readings


@settings(max_examples=40, deadline=None, derandomize=True)
@given(st.floats(1e-3, 900.0), st.floats(0.3, 6.0), st.integers(2, 40))
def test_the_band_has_the_same_number_of_terms_whatever_its_width(f_min, decades, terms):
    """Every parameter set compiles to one structure (so a batch of candidates stacks): the
    power-law band has exactly ``terms`` Maxwell terms for any placement and width."""
    fam = FilledRubberFamily(SCALE, {"terms": terms})
    v = fam.initial()
    v[8], v[9] = f_min, decades
    matrix = fam.coupling(v).elements[2]
    assert matrix.terms().shape[0] == terms
    assert matrix.max_frequency == pytest.approx(f_min * 10 ** decades, rel=1e-12)
    assert Coupling.stack([fam.coupling(v), fam.coupling(fam.initial())]).n_sets == 2


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(3))
def test_first_guess_reproduces_the_readings_of_its_own_closed_form(seed):
    """Readings of a random parameter set's closed form (four amplitudes x three frequencies, the
    band known): the guess's K* meets them within 1 % (the split between spring and network
    need not be unique, the stiffness it predicts must be)."""
    fam = FilledRubberFamily(SCALE)
    rng = np.random.default_rng(100 + seed)
    truth = _random_values(fam, rng)
    a, f = np.meshgrid(np.radians([0.2, 0.6, 1.5, 3.0]), [20.0, 35.0, 55.0])
    k_obs = fam.harmonic_stiffness(truth, a.ravel(), f.ravel())
    x0 = fam.initial()
    x0[8:10] = truth[8:10]
    guess = fam.guess_from_readings(a.ravel(), f.ravel(), k_obs, x0, np.zeros(len(x0), bool))
    got = fam.harmonic_stiffness(guess, a.ravel(), f.ravel())
    assert np.max(np.abs(got - k_obs) / np.abs(k_obs)) < 0.01
    # fewer than three readings: the guess is the start
    assert guess is not x0 and fam.guess_from_readings(a.ravel()[:2], f.ravel()[:2], k_obs[:2], x0,
                                                       np.zeros(len(x0), bool)) is x0


#: The test types fitted (:func:`random_couplings.servo_records`' first three: the slow ramps, the
#: frequency and the amplitude sweep, 6.5 s of record); the band-limited random profile (5 s) is
#: left out of the fits: of another noise draw it is the hold-out, a record of a kind the fit never
#: saw (measured: the seeds' filled_rubber fits 3.9 and 3.3 s of CPU instead of 5.7 and 4.8, hold-out
#: 0.50 % and 0.54 %; the compare-models ranking below 8.7 s instead of 16.6).
FITTED = slice(0, 3)


@pytest.fixture(scope="session")  # kept when worksteal splits this file: a second block reuses it
def servo_case():
    """``servo_case(seed)``: a seeded random coupling of the family's structure (not the family's
    discretisation of the band), its test-type records (0.5 % noise; :data:`FITTED`), its random
    profile of another noise draw as the hold-out and the identification with it; made once per
    module (the ranking reuses seed 1's)."""
    made: dict[int, tuple] = {}

    def case(seed: int) -> tuple[list, Identification]:
        if seed not in made:
            truth = parse_coupling(random_truth("filled_rubber", np.random.default_rng(30_000 + seed)))
            data = servo_records(truth, seed)[FITTED]
            made[seed] = data, identify("filled_rubber", data, holdout=servo_records(truth, 50 + seed)[-1:])
        return made[seed]

    return case


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(2))
def test_servo_records_of_random_filled_rubber_are_recovered(seed, servo_case):
    """Seeded random couplings of the family's structure (not the family's discretisation of the
    band): the test-type records (0.5 % noise) identified to a good fit, the hold-out (the random
    profile, a kind of record the fit never saw) predicted within 1 %."""
    _, result = servo_case(seed)
    assert result.converged and not result.verdict.poor
    assert result.holdout_error.nrmse < 0.01


@pytest.mark.slow
def test_compare_models_ranks_filled_rubber_first_only_where_the_truth_is_filled_rubber(servo_case):
    """On a filled-rubber-like coupling's records filled_rubber beats every other servo family
    with one parameter set by far (BIC); on the six-parameter model's own records (a simpler family
    exact) it does not rank first, though it fits them well too (a good fit: the criterion's
    parameter count decides). The filled-rubber records and their fit are the recovery test's
    seed 1 (the same data and call: ``previous`` and the hold-out do not change a filled_rubber
    fit or its BIC). Both sets are the test types of :data:`FITTED` (on the six-parameter model's
    with its random profile too, filled_rubber's fit was poor, BIC 17881 against 903, and its
    global search cost 8.8 s of the test's 16.6). The elastoslide runs its global search in any
    case (``search="always"``; the better of it and the staged fit is kept, so the competitor is
    at least as strong as the command line's): its draws of the exponent p are checked."""
    filled, fitted = servo_case(1)
    six = servo_records(parse_coupling(random_truth("zerodim6", np.random.default_rng(500))), 2)[FITTED]
    for data, first, kinds in ((filled, "filled_rubber", ("zerodim6", "elastoslide", "masing", "pfeffer", "filled_rubber")),
                               (six, "zerodim6", ("zerodim6", "filled_rubber"))):
        results = {}
        for kind in kinds:
            search = "always" if kind == "elastoslide" else "auto"
            results[kind] = (fitted if data is filled and kind == "filled_rubber"
                             else identify(kind, data, previous=results, search=search))
        table = ranking_table(results, data)
        assert table["family"].iloc[0] == first, table[["family", "bic", "verdict"]]
        if "elastoslide" in results:  # its global search draws p among the odd candidates (it once sampled 1-99)
            assert "global_search" in results["elastoslide"].extra
            assert results["elastoslide"].parameters["p"] in (3, 5, 7, 9, 11)
        if first == "filled_rubber":
            assert table["delta_bic"].iloc[1] > 10
        else:
            assert not results["filled_rubber"].verdict.poor  # outranked though it fits


def test_translational_records_name_parameters_in_metres_and_newtons(monkeypatch):
    """A bushing of the family's structure read as m / N: the same identification as its
    torsional twin (the same numbers out of every stage: the scale and bounds, the first guess
    from the harmonic readings, the joint least squares), parameters named for the records'
    units, the coupling translational. Sameness needs no converged fit: both run with one
    start of the first guess's fit and a few evaluations of the joint fit, where a units slip
    anywhere on that path already changes the numbers."""
    from droptower.identify.families import filled_rubber as module
    from droptower.identify.report import result_dict
    from droptower.identify.data import make_segment
    from droptower.io.fields import field_name

    monkeypatch.setattr(module, "GUESS_STARTS", 1)
    data = random_truth("filled_rubber", np.random.default_rng(30_002))
    twin = parse_coupling(data)
    records = servo_records(twin, 3)
    trans = [make_segment(s.measured_angle * 0 + np.arange(s.measured_angle.size) * s.dt_s, s.measured_angle,
                          s.measured_torque, name=s.name, units="translational") for s in records]
    budget = {"max_nfev": 4}
    got = identify("filled_rubber", trans, options=budget, search="never")
    ref = identify("filled_rubber", records, options=budget, search="never")
    assert got.coupling.units == "translational" and ref.coupling.units == "torsional"
    assert got.extra["readings"] == ref.extra["readings"] >= 3  # the first guess read the sine blocks
    assert got.fit_error.nrmse == pytest.approx(ref.fit_error.nrmse, rel=1e-6)
    names = result_dict(got)["parameters"]
    assert {"k_n_per_m", "a_n_per_m3", "critical_displacement_m", "breakdown_displacement_m"} <= set(names)
    for name, entry in result_dict(ref)["parameters"].items():
        assert names[field_name(name, "translational")]["value"] == pytest.approx(entry["value"], rel=1e-6), name


def test_export_fmu_writes_an_identified_filled_rubber_coupling(tmp_path):
    """An identified filled_rubber coupling (as ``identify --out`` writes it) exported as an FMU:
    FMPy's torque is the core's at the same step."""
    fmpy = pytest.importorskip("fmpy")
    pytest.importorskip("pythonfmu")
    from droptower.rheology import coupling_to_toml

    fam = FilledRubberFamily(SCALE)
    coupling = fam.coupling(_random_values(fam, np.random.default_rng(7)))
    path = tmp_path / "identified.toml"
    path.write_text(coupling_to_toml(coupling))
    h = 1.0 / 38_400.0
    assert main(["export-fmu", str(path), "--out", str(tmp_path / "fr.fmu"), "--internal-step-s", repr(h)]) == 0
    t = np.arange(600) * h
    angle = np.radians(2.0) * np.exp(-25.0 * t) * np.sin(2 * np.pi * 60.0 * t)
    rate = np.append(np.diff(angle) / h, 0.0)  # carries the angle to the next sample over one step
    table = np.array(list(zip(t, angle, rate)), dtype=[("time", float), ("angle_rad", float),
                                                       ("angle_rate_rad_per_s", float)])
    out = fmpy.simulate_fmu(str(tmp_path / "fr.fmu"), start_time=0.0, stop_time=float(t[-1]), step_size=h,
                            input=table, output=["torque_nm"], output_interval=h)
    np.testing.assert_allclose(out["torque_nm"], coupling.respond(angle, h), rtol=1e-9,
                               atol=1e-9 * float(np.max(np.abs(coupling.respond(angle, h)))))


def test_design_and_compare_models_offer_the_family(capsys):
    for command in (["design", "--help"], ["compare-models", "--help"]):
        assert main(command) == 0
        assert "filled_rubber" in capsys.readouterr().out.replace("\n", " ").replace(" ", "")


@pytest.mark.slow
def test_design_for_identification_of_filled_rubber(tmp_path, capsys):
    """``design --for-identification filled_rubber``: the family fitted to the predicted decays,
    a plan of the budget with the predicted standard errors of its free parameters (drops chosen
    from part of the rig's range: fewer predicted decays to fit, the same route)."""
    import json

    out = tmp_path / "ident.toml"
    assert main(["design", "--for-identification", "filled_rubber", "--max-tests", "4", "--amplitude-deg", "0.5:2",
                 "--frequency-hz", "20:45", "--out", str(out), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["tests"] == 4 and doc["family"] == "filled_rubber"
    assert set(doc["predicted_stderr"]) == set(FilledRubberFamily(SCALE).names)


#: The drop tests' family: a network of 8 Jenkins elements instead of 32 (a coarser discretisation of
#: the same yield distribution; each test's core steps cost a fraction). The family's defaults on
#: 12-drop campaigns are measured by ``benchmarks/bench_identify.py --filled-rubber`` (items 10-11).
DROP_OPTIONS = {"n": 8}
#: Periods of each decay compared after the impact: two instead of the reading's default three
#: (every re-simulation of the fit costs two thirds; the first cycles' amplitudes, where the
#: couplings' amplitude dependence shows, are all kept). The default's figures on 12-drop
#: campaigns: ``benchmarks/bench_identify.py --filled-rubber``.
DROP_CYCLES = 2.0


def _drop_fit_agreement(truth: Coupling, tmp_path, seed: int, heights: tuple[float, ...] = (0.2, 1.0, 3.0),
                        duration_s: float = 0.25):
    """Noisy rig logs of ``truth``, the drop ``heights`` (m) on each of the three inertias (noise
    seeds from ``seed``), ``duration_s`` long after the impact, their first :data:`DROP_CYCLES`
    periods identified with filled_rubber (:data:`DROP_OPTIONS`): (the fit, its bench agreement
    over the tested range). A log shorter than the rig's 0.25 s gives the same decays (the angle
    and torque to the bit, the impact's rate to 1e-13) where every compared window ends inside it
    (checked: 20 ms before its end), for a fraction of the rig's simulation (it runs on through
    the drop mass's rebounds)."""
    from droptower.identify.dropfit import DropFitSettings, identify_drops, servo_agreement
    from droptower.identify.droplogs import ReadSettings, read_decays
    from droptower.rig.config import load_rig
    from droptower.rig.simulate import DropTest
    from droptower.rig.simulate import simulate as rig_simulate

    tests = [DropTest(j, m, h, 0.0, 0, seed + 10 * i + k) for i, (j, m) in enumerate([(0.1557, 1.0), (0.359, 2.0),
                                                                                      (0.5233, 2.0)])
             for k, h in enumerate(heights)]
    paths = [r.write_log(tmp_path / f"test_{k}.parquet")
             for k, r in enumerate(rig_simulate(load_rig("rapp2022"), truth, tests, duration_s))]
    decays, excluded = read_decays(paths, ReadSettings(cycles=DROP_CYCLES))
    assert not excluded and max(d.time_s[-1] for d in decays) <= duration_s - 0.02  # no window cut by the log's end
    result = identify_drops("filled_rubber", decays, settings=DropFitSettings(holdout_fraction=0.0),
                            options=DROP_OPTIONS)
    return result, servo_agreement(result.coupling, truth, decays, n_amplitudes=3, n_frequencies=2)


@pytest.mark.slow
@pytest.mark.parametrize("seed", [0])
def test_drop_tests_of_a_random_filled_rubber_coupling_predict_its_bench(seed, tmp_path):
    """A seeded random coupling of the family's structure (its own band discretisation, numbers
    no preset has; its network of the family's :data:`DROP_OPTIONS` elements), nine noisy rig logs
    over the three inertias, :data:`DROP_CYCLES` periods of each: the identified coupling's bench K'
    within 3 % and loss factor within 10 % RMS over the tested range (measured 0.02 % and 0.18 %;
    0.01 % and 0.15 % over three periods, as with 32 elements in both), a good fit (0.48 x the
    noise, 0.46 x over three periods; six logs leave it at 1.8 x, and 2.2 x over three). The
    issue's 12-drop figures: ``benchmarks/bench_identify.py --filled-rubber``."""
    data = random_truth("filled_rubber", np.random.default_rng(31_000 + seed))
    data["element"][1]["n"] = DROP_OPTIONS["n"]  # the family's network (a finer one is not the family's structure)
    result, agree = _drop_fit_agreement(parse_coupling(data), tmp_path, 2000, duration_s=0.2)  # decays end by 0.147 s
    assert agree["storage_stiffness_rms"] <= 0.03 and agree["loss_factor_rms"] <= 0.10, agree
    assert not result.verdict.poor


@pytest.mark.slow
def test_drop_tests_of_a_coupling_whose_viscous_loss_grows_with_the_amplitude_predict_its_bench(tmp_path):
    """A seeded six-parameter form with a friction bank (random_couplings' zerodim6_friction: its
    Maxwell branch stiffens with its deformation, so its loss factor at 30 Hz rises by half from
    0.4 to 2.6 deg, which only the family's stiffening Maxwell branch represents; the first search,
    without it, is poor, the wider one frees it), six noisy rig logs over the three inertias,
    :data:`DROP_CYCLES` periods of each: the identified coupling's bench K' within 5 % and loss
    factor within 10 % RMS over the tested range (the issue's bounds for other structures; measured
    0.21 % and 0.48 %, 0.27 % and 0.97 % over three periods), the decays within 4 x the noise
    (measured 1.6, 2.2 over three periods: the truth's Prandtl bank, a Masing yield distribution,
    is not the family's Iwan network, so the verdict's limit of 2 is not demanded). Three draws of
    this structure on 12-drop campaigns: ``benchmarks/bench_identify.py --filled-rubber``."""
    truth = parse_coupling(random_truth("zerodim6_friction", np.random.default_rng(32_004)))
    eta = run_grid(truth, np.radians([0.4, 2.6]), [30.0], cycles=2, run_in_cycles=3,
                   simulation_rate_hz=9600.0)["loss_factor"].to_numpy()
    assert eta[1] > 1.3 * eta[0]  # the draw has the mechanism under test
    result, agree = _drop_fit_agreement(truth, tmp_path, 2100, heights=(0.2, 3.0), duration_s=0.12)  # end by 0.088 s
    assert agree["storage_stiffness_rms"] <= 0.05 and agree["loss_factor_rms"] <= 0.10, agree
    assert result.verdict.error_over_noise < 4.0, result.verdict
    assert "kv_gain_nm_per_rad2" in result.search.get("deferred_freed", [])  # the first search, without it, was poor
