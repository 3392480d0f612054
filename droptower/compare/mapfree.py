"""The map-free check of the drop-tower method: drop tests placed on servo points.

The map-vs-servo validation (:mod:`droptower.compare.map_vs_servo`) mixes two errors: the map's
misfit and the drop tower's own bias. Here the map is taken out: for every servo point
(amplitude A, frequency f) a virtual drop test is designed whose decay lands on it — the
lever inertia J sets the frequency, the lever's rate after the impact sets the amplitude (both
solved by Newton's method on the fast free decay, :func:`place_drop_tests`) — and that test is
run through the whole pipeline (pymunk rig, sensors, log, extraction). Then, per point:

- decay vs servo: the extracted stiffness and damping ratio against the servo bench at the
  decay's own amplitude and frequency (storage stiffness K', the drop-tower-equivalent d;
  docs/theory.md#damping-measures), with the loss factor and the decay ratio r = delta/omega alongside;
- map vs decay: the map at the decay's point against the decay (the map's misfit there);
- map vs servo: the map at the servo point against the bench (what validation reports).

The drop height follows from the rate by the impact law (docs/theory.md#impact) with the heaviest of the
rig's drop masses that still rebounds clearly (m1 <= k m2 / 2), so no second impact.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import tomli_w

from droptower import sdof
from droptower.compare.map_vs_servo import deviation_stats
from droptower.errors import DroptowerError
from droptower.damped_cosine import fit_decay, start_frequency_and_decay
from droptower.maps import MapFit
from droptower.rates import RIG_SAMPLE_RATE_HZ
from droptower.rheology import Coupling
from droptower.rig.config import RigConfig
from droptower.rig.predictions import free_decay
from droptower.rig.preload import pretwist
from droptower.servo.steady import steady_state

#: Newton iterations on (log J, log rate) and the relative tolerance on (A, f)
ITERATIONS = 12
TOLERANCE = 2e-3
STEP_S = 1 / RIG_SAMPLE_RATE_HZ


@dataclass(frozen=True)
class Placement:
    """Per point: inertia_kgm2, rate_rad_per_s (after the impact), drop_mass_kg, drop_height_m,
    and the fast decay's amplitude_deg and frequency_hz it reached."""

    table: pd.DataFrame


def _decay_points(coupling: Coupling, rig: RigConfig, inertia: np.ndarray, rate: np.ndarray) -> np.ndarray:
    """(B, 2): amplitude (deg, window middle) and frequency (Hz) of each free decay's first
    cycle, fitted like the extractor (docs/theory.md#extraction)."""
    at_rest = pretwist(coupling, np.zeros(inertia.size), rig.simulation.preload_ramp_s, rig.simulation.preload_hold_s)
    dec = free_decay(coupling, inertia, rate, at_rest, STEP_S)
    t = dec.time_s[1:]
    out = np.empty((inertia.size, 2))
    for i, a in enumerate(dec.angle_rad[:, 1:]):
        omega0, delta0 = start_frequency_and_decay(t, a, 0.0)
        window = t <= 2 * np.pi / omega0
        amp, delta, omega, _ = fit_decay(t[window], a[window], omega0, delta0).params
        out[i] = np.degrees(amp * np.exp(-delta * t[window][-1] / 2)), omega / (2 * np.pi)
    return out


def place_drop_tests(coupling: Coupling, rig: RigConfig, amplitude_deg: np.ndarray, frequency_hz: np.ndarray
                     ) -> Placement:
    """Solve J and the impact rate so that each drop test's decay lands on (A, f)."""
    a_t = np.asarray(amplitude_deg, float)
    f_t = np.asarray(frequency_hz, float)
    ss = steady_state(coupling, np.radians(a_t), f_t)
    log_j = np.log(ss.storage_stiffness_nm_per_rad / (2 * np.pi * f_t) ** 2)   # f = sqrt(K'/J) / 2 pi
    log_rate = np.log(np.radians(a_t) * 2 * np.pi * f_t * 1.3)                   # A ~ rate / w, less the decay
    target = np.log(np.column_stack([a_t, f_t]))
    h = 1e-3
    reached = np.exp(target)
    for _ in range(ITERATIONS):
        trial_j = np.concatenate([log_j, log_j + h, log_j])
        trial_r = np.concatenate([log_rate, log_rate, log_rate + h])
        got = np.log(_decay_points(coupling, rig, np.exp(trial_j), np.exp(trial_r)))
        n = a_t.size
        base, dj, dr = got[:n], (got[n:2 * n] - got[:n]) / h, (got[2 * n:] - got[:n]) / h
        reached = np.exp(base)
        miss = target - base
        if np.max(np.abs(miss)) < TOLERANCE:
            break
        jac = np.stack([dj, dr], axis=-1)                                    # (n, 2 outputs, 2 inputs)
        step = np.linalg.solve(jac, miss[..., None])[..., 0]
        step = np.clip(step, -0.5, 0.5)
        log_j, log_rate = log_j + step[:, 0], log_rate + step[:, 1]
    else:
        raise DroptowerError(f"cannot place drop tests on {int(np.sum(np.max(np.abs(target - np.log(reached)), axis=1) >= TOLERANCE))} "
                             "servo point(s): the decay does not reach their amplitude and frequency")
    inertia, rate = np.exp(log_j), np.exp(log_rate)
    k, lever = rig.restitution, rig.lever_length_m
    m2 = inertia / lever ** 2
    # the heaviest of the rig's drop masses that still rebounds clearly (m1 <= k m2 / 2): the
    # lowest drop height; lighter than all of them only where none does
    masses = np.sort(np.asarray(rig.drop_masses_kg, float))
    m1 = np.array([masses[masses <= 0.5 * k * m].max() if np.any(masses <= 0.5 * k * m) else 0.5 * k * m for m in m2])
    v1 = rate * lever * (m1 + m2) / (m1 * (1 + k))                          # docs/theory.md#impact solved for v1
    return Placement(pd.DataFrame({"inertia_kgm2": inertia, "rate_rad_per_s": rate, "drop_mass_kg": m1,
                                   "drop_height_m": v1 ** 2 / (2 * rig.gravity_m_per_s2), "amplitude_deg": reached[:, 0],
                                   "frequency_hz": reached[:, 1]}))


def placement_plan(placement: Placement, path: Path, name: str = "map_free_check") -> Path:
    """A test plan (DOE TOML) of the placed tests: one group each, one height, no preload."""
    groups = [{"name": f"point {i + 1}", "inertia_kgm2": float(r.inertia_kgm2), "drop_mass_kg": float(r.drop_mass_kg),
               "heights_m": [float(r.drop_height_m)]} for i, r in enumerate(placement.table.itertuples())]
    doc = {"name": name, "description": "virtual drop tests whose decays land on servo points (map-free check)",
           "base_seed": 4004000, "repeats": 1, "heights_m": groups[0]["heights_m"], "preloads_nm": [0.0],
           "group": groups}
    path.write_text(tomli_w.dumps(doc))
    return path


@dataclass(frozen=True)
class MapFreeCheck:
    """``table``: one row per servo point (module docstring); ``summary``: RMS / max deviations
    (percent) of stiffness, damping ratio, loss factor and r for ``decay_vs_servo``,
    ``map_vs_decay`` and ``map_vs_servo``."""

    table: pd.DataFrame
    summary: dict[str, Any]


def compare_decays(servo_points: pd.DataFrame, decays: pd.DataFrame, coupling: Coupling, fit: MapFit | None
                   ) -> MapFreeCheck:
    """The three comparisons of the module docstring. ``servo_points``: amplitude_deg,
    frequency_hz, servo_stiffness_nm_per_deg, servo_damping_ratio (the bench at the servo
    point); ``decays``: the extracted tests in the same order (amplitude_deg, frequency_hz,
    stiffness_nm_per_deg, damping_ratio)."""
    a_s, f_s = servo_points["amplitude_deg"].to_numpy(float), servo_points["frequency_hz"].to_numpy(float)
    a_d, f_d = decays["amplitude_deg"].to_numpy(float), decays["frequency_hz"].to_numpy(float)
    c_d, d_d = decays["stiffness_nm_per_deg"].to_numpy(float), decays["damping_ratio"].to_numpy(float)
    at_decay = steady_state(coupling, np.radians(a_d), f_d)                   # the bench at the decay's point
    c_b = np.radians(at_decay.storage_stiffness_nm_per_rad)
    d_b = sdof.drop_tower_equivalent_damping_ratio(at_decay.loss_factor)
    c_s, d_s = servo_points["servo_stiffness_nm_per_deg"].to_numpy(float), servo_points["servo_damping_ratio"].to_numpy(float)

    def deviations(c, d, c_ref, d_ref):
        r, r_ref = sdof.decay_ratio(d), sdof.decay_ratio(d_ref)
        eta, eta_ref = sdof.loss_factor(r, 1.0), sdof.loss_factor(r_ref, 1.0)
        return {"stiffness": 100 * (c / c_ref - 1), "damping": 100 * (d / d_ref - 1),
                "loss_factor": 100 * (eta / eta_ref - 1), "decay_ratio": 100 * (r / r_ref - 1)}

    pairs = {"decay_vs_servo": deviations(c_d, d_d, c_b, d_b)}
    table = pd.DataFrame({"servo_amplitude_deg": a_s, "servo_frequency_hz": f_s, "decay_amplitude_deg": a_d,
                          "decay_frequency_hz": f_d, "decay_stiffness_nm_per_deg": c_d, "decay_damping_ratio": d_d,
                          "bench_at_decay_stiffness_nm_per_deg": c_b, "bench_at_decay_damping_ratio": d_b,
                          "servo_stiffness_nm_per_deg": c_s, "servo_damping_ratio": d_s})
    if fit is not None:
        c_md, d_md = fit.stiffness_nm_per_deg(a_d, f_d), fit.damping_ratio(a_d, f_d)
        c_ms, d_ms = fit.stiffness_nm_per_deg(a_s, f_s), fit.damping_ratio(a_s, f_s)
        pairs["map_vs_decay"] = deviations(c_md, d_md, c_d, d_d)
        pairs["map_vs_servo"] = deviations(c_ms, d_ms, c_s, d_s)
        table = table.assign(map_at_decay_stiffness_nm_per_deg=c_md, map_at_decay_damping_ratio=d_md,
                             map_stiffness_nm_per_deg=c_ms, map_damping_ratio=d_ms)
    for name, dev in pairs.items():
        table = table.assign(**{f"{name}_{q}_deviation_pct": v for q, v in dev.items()})
    summary = {name: deviation_stats(dev["stiffness"], dev["damping"], dev["loss_factor"], dev["decay_ratio"])
               for name, dev in pairs.items()}
    return MapFreeCheck(table, summary)


def format_check(check: MapFreeCheck) -> str:
    """The summary as text, one line per comparison."""
    lines = [f"{'map-free check':<18}{'points':>7}{'stiffness rms':>15}{'max':>8}{'d rms':>8}{'max':>8}"
             f"{'eta rms':>9}{'r rms':>8}   (deviation, %)"]
    for name, s in check.summary.items():
        lines.append(f"{name.replace('_', ' '):<18}{s['n_points']:>7}{s['stiffness_rms_deviation_pct']:>15.2f}"
                     f"{s['stiffness_max_deviation_pct']:>8.2f}{s['damping_rms_deviation_pct']:>8.2f}"
                     f"{s['damping_max_deviation_pct']:>8.2f}{s['loss_factor_rms_deviation_pct']:>9.2f}"
                     f"{s['decay_ratio_rms_deviation_pct']:>8.2f}")
    return "\n".join(lines)


def run_check(coupling: Coupling, coupling_file: str | Path, rig_file: str | Path, rig: RigConfig,
              servo_points: pd.DataFrame, fit: MapFit | None, folder: Path, *, workers: int | None = None,
              progress: bool = False) -> MapFreeCheck:
    """Place a drop test on every servo point, run them as a campaign into ``folder`` (logs,
    extraction: the real pipeline) and compare (module docstring)."""
    from droptower.campaign import run_campaign

    if servo_points.empty:
        raise DroptowerError("map-free check: no servo points to place drop tests on")
    target = servo_points[["amplitude_deg", "frequency_hz"]].to_numpy(float)
    folder.mkdir(parents=True, exist_ok=True)
    aim = target.copy()
    for attempt in range(2):
        # the pipeline's impact (a 0.3 ms contact in pymunk, sensors) lands a little off the
        # fast decay: one output-space correction of the aim brings it onto the point
        placement = place_drop_tests(coupling, rig, aim[:, 0], aim[:, 1])
        sub = folder / f"attempt{attempt + 1}"
        sub.mkdir(parents=True, exist_ok=True)
        plan = placement_plan(placement, sub / "map_free_plan.toml")
        run = run_campaign(sub / "campaign", rig_file, coupling_file, plan, workers=workers, resume=True,
                           progress=progress)
        results = run.results
        if len(results) != len(target) or not (results["status"] == "done").all():
            raise DroptowerError(f"map-free check: {int((results['status'] != 'done').sum())} placed drop test(s) "
                                 "failed", file=sub / "campaign")
        landed = results.sort_values("test_id")[["amplitude_deg", "frequency_hz"]].to_numpy(float)
        aim = aim * target / landed
    results = results.sort_values("test_id").reset_index(drop=True)  # one test per group, in the plan's order
    check = compare_decays(servo_points.reset_index(drop=True), results, coupling, fit)
    check.table.insert(0, "drop_height_m", placement.table["drop_height_m"].to_numpy())
    check.table.insert(0, "drop_mass_kg", placement.table["drop_mass_kg"].to_numpy())
    check.table.insert(0, "inertia_kgm2", placement.table["inertia_kgm2"].to_numpy())
    return check
