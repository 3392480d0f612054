"""The servo bench's own expanded uncertainty (droptower.uncertainty.bench, evaluate-servo
--uncertainty): type A from the cycles' scatter, type B from the stated calibrations, checked
against the closed forms and against the truth of noisy Kelvin-Voigt records."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from droptower.errors import DroptowerError
from droptower.servo import evaluate_records
from droptower.uncertainty.bench import bench_u95
from test_servo_records import C, FS, K, _run, _write_csv


def _noisy(tmp_path, seed: int, sigma: float = 2.0, f: float = 8.0, n_cycles: int = 12) -> str:
    a, w = math.radians(1.0), 2 * math.pi * f
    t = np.arange(int((n_cycles + 2) / f * FS)) / FS
    x = a * np.sin(w * t)
    y = K * x + C * a * w * np.cos(w * t) + np.random.default_rng(seed).normal(0.0, sigma, t.size)
    return _write_csv(tmp_path / f"noisy_{seed}.csv", {"time_s": t, "angle_rad": x, "torque_nm": y})


def test_the_budget_is_the_closed_form(tmp_path):
    """U95(K') = k·√((s/√n)² + (K'·√(u_T² + u_φ²))²), k of Welch-Satterthwaite's ν_eff; the loss
    factor's carries no calibration: k = t_0.975(n − 1)."""
    from scipy.stats import t
    table = evaluate_records([_noisy(tmp_path, 1)], cycles=10)
    out = bench_u95(table, torque_calibration_rel=0.005, angle_calibration_rel=0.003)
    r = out.iloc[0]
    n = r["evaluated_cycles"]
    u_a = r["storage_stiffness_std_nm_per_deg"] / math.sqrt(n)
    u_c = math.hypot(u_a, math.hypot(0.005, 0.003) * r["storage_stiffness_nm_per_deg"])
    k = t.ppf(0.975, u_c ** 4 / (u_a ** 4 / (n - 1)))
    assert 1.959 < k < 2.0  # the calibrations dominate: ν_eff large, k near the normal 1.96
    assert r["storage_stiffness_nm_per_deg_U95"] == pytest.approx(k * u_c, rel=1e-12)
    assert r["loss_factor_U95"] == pytest.approx(t.ppf(0.975, n - 1) * r["loss_factor_std"] / math.sqrt(n), rel=1e-12)
    assert r["bench_uncertainty_not_given"] == ""
    assert bench_u95(table).iloc[0]["bench_uncertainty_not_given"] == "torque_calibration_rel;angle_calibration_rel"
    with pytest.raises(DroptowerError, match="torque_calibration_rel"):
        bench_u95(table, torque_calibration_rel=-0.1)


def test_the_scatter_interval_holds_the_truth(tmp_path):
    """No calibration error: the intervals (Student's k for the cycles' ν = n − 1) of 20 noisy
    records (10 cycles evaluated) hold K' = k and η = cω/k in all but at most three (95 %: one
    expected; P(more than 3 misses) < 2 %). With k = 2 they missed K' four times: t_9 is wider."""
    rows = bench_u95(evaluate_records([_noisy(tmp_path, s) for s in range(20)], cycles=10))
    w = 2 * math.pi * 8.0
    k_deg = math.radians(K)
    assert (np.abs(rows["storage_stiffness_nm_per_deg"] - k_deg) > rows["storage_stiffness_nm_per_deg_U95"]).sum() <= 3
    assert (np.abs(rows["loss_factor"] - C * w / K) > rows["loss_factor_U95"]).sum() <= 3


def test_evaluate_servo_prints_the_bench_u95_and_refuses_a_bad_spec(tmp_path, capsys):
    record = _noisy(tmp_path, 3)
    code, out, _ = _run(capsys, ["evaluate-servo", record, "--json", "--uncertainty", "torque_calibration_rel=0.005"])
    assert code == 0
    row = json.loads(out)[0]
    assert row["storage_stiffness_nm_per_deg_U95"] >= 1.959 * 0.005 * row["storage_stiffness_nm_per_deg"]
    assert row["bench_uncertainty_not_given"] == "angle_calibration_rel"
    code, _, err = _run(capsys, ["evaluate-servo", record, "--uncertainty", "torque=1"])
    assert code == 2 and "--uncertainty 'torque=1'" in err and "Traceback" not in err
