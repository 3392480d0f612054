"""The coupling FMU (``droptower export-fmu``), loaded and simulated by FMPy: its torque is
``Coupling.respond``'s at the same step, on a sine, a decay and random histories, for any
communication step, with its parameters changed, and for an identified model on the
identification's hold-out data."""
from __future__ import annotations

import numpy as np
import pytest

from droptower import load_coupling
from droptower.cli.main import main
from droptower.rheology.loader import parse_coupling

fmpy = pytest.importorskip("fmpy")
pytest.importorskip("pythonfmu")

H = 1.0 / 38_400.0
N = 600


@pytest.fixture(scope="module")
def nr60(tmp_path_factory):
    """The default coupling (spring + payne + power law: nonlinear, with memory) as an FMU."""
    path = tmp_path_factory.mktemp("fmu") / "nr60.fmu"
    assert main(["export-fmu", "rapp2022_nr60", "--out", str(path)]) == 0
    return path


def _run(fmu, angle: np.ndarray, step_s: float, rate: np.ndarray | None = None, **start_values) -> np.ndarray:
    """The FMU's torque at every communication point, the input table sampled at those points."""
    names = [("time", float), ("angle_rad", float)] + ([("angle_rate_rad_per_s", float)] if rate is not None else [])
    t = np.arange(angle.size) * step_s
    columns = [t, angle] + ([rate] if rate is not None else [])
    table = np.array(list(zip(*columns)), dtype=names)
    result = fmpy.simulate_fmu(str(fmu), start_time=0.0, stop_time=float(t[-1]), step_size=step_s, input=table,
                               output=["torque_nm"], output_interval=step_s, start_values=start_values,
                               validate=True)
    assert result["time"].size == angle.size
    return np.asarray(result["torque_nm"])


def _histories() -> dict[str, np.ndarray]:
    t = np.arange(N) * H
    rng = np.random.default_rng(11)
    return {
        "sine": np.radians(1.5) * np.sin(2 * np.pi * 40.0 * t),
        "decay": np.radians(2.0) * np.exp(-25.0 * t) * np.sin(2 * np.pi * 60.0 * t) + np.radians(0.3),
        "random": np.cumsum(rng.normal(0.0, np.radians(0.05), N)),
    }


def _forward_rate(angle: np.ndarray, step_s: float) -> np.ndarray:
    """The rate that carries the angle to the next sample over one step (last: held)."""
    return np.append(np.diff(angle) / step_s, 0.0)


@pytest.mark.parametrize("kind", ["sine", "decay", "random"])
def test_fmu_torque_is_respond_at_the_same_step(nr60, kind):
    angle = _histories()[kind]
    want = load_coupling("rapp2022_nr60").respond(angle, H)
    got = _run(nr60, angle, H, rate=_forward_rate(angle, H))
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12 * float(np.max(np.abs(want))))


def test_a_held_angle_and_a_longer_communication_step(nr60):
    """Without a rate the angle is held over the communication step (FMI's zero-order hold):
    four internal steps per communication step are respond on the held history."""
    angle = _histories()["random"][:150]
    # the start: one internal step from the relaxed state to the first angle; then each angle
    # held over the four internal steps of its communication step
    held = np.concatenate([angle[:1], np.repeat(angle[:-1], 4)])
    want = load_coupling("rapp2022_nr60").respond(held, H)
    got = _run(nr60, angle, 4 * H)
    np.testing.assert_allclose(got, want[::4], rtol=0, atol=1e-12 * float(np.max(np.abs(want))))


def test_parameters_are_the_coupling_numbers(nr60):
    md = fmpy.read_model_description(str(nr60))
    params = {v.name: float(v.start) for v in md.modelVariables if v.causality == "parameter"}
    assert params["internal_step_s"] == pytest.approx(H)
    assert params["element_1.stiffness"] == load_coupling("rapp2022_nr60").elements[0].stiffness
    angle = _histories()["sine"][:200]
    stiff = parse_coupling({"name": "x", "element": [
        {**el.model_dump(exclude_none=True), **({"stiffness": 2.0 * el.stiffness} if i == 0 else {})}
        for i, el in enumerate(load_coupling("rapp2022_nr60").elements)]})
    want = stiff.respond(angle, H)
    doubled = {"element_1.stiffness": params["element_1.stiffness"] * 2}
    got = _run(nr60, angle, H, rate=_forward_rate(angle, H), **doubled)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12 * float(np.max(np.abs(want))))


def test_fmu_of_an_identified_model_reproduces_its_holdout(tmp_path):
    from droptower.identify import identify
    from droptower.identify.fit import metrics
    from test_identify_helpers import fitting_histories, random_history, records
    from droptower.fmu import build_fmu

    truth = load_coupling("seed000_six_parameter")
    data, _ = records(truth, fitting_histories())
    held, _ = records(truth, random_history(duration_s=4.5), seed=5)
    result = identify("zerodim6", data, holdout=held)
    (segment,) = held
    # the identification's own step (its substeps option is 1): the model it fitted and tested
    fmu = build_fmu(result.coupling, tmp_path / "identified.fmu", internal_step_s=segment.dt_s)
    torque = _run(fmu, segment.angle_rad, segment.dt_s, rate=_forward_rate(segment.angle_rad, segment.dt_s))
    got = metrics(held, [torque])
    assert got.n_samples == result.holdout_error.n_samples
    assert got.rmse_nm == pytest.approx(result.holdout_error.rmse_nm, rel=1e-9)
    assert got.nrmse == pytest.approx(result.holdout_error.nrmse, rel=1e-9)


def test_bad_requests_are_one_line(tmp_path, capsys):
    assert main(["export-fmu", "rapp2022_nr60", "--out", str(tmp_path / "x.zip")]) == 2
    assert "must end in .fmu" in capsys.readouterr().err
    assert main(["export-fmu", "rapp2022_nr60", "--out", str(tmp_path / "x.fmu"), "--internal-step-s", "0"]) == 2
    assert "--internal-step-s" in capsys.readouterr().err
    assert main(["export-fmu", "no_such_coupling", "--out", str(tmp_path / "x.fmu")]) == 2
    assert not list(tmp_path.iterdir())
