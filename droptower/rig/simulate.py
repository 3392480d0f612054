"""Run drop tests on the virtual drop tower: test conditions -> pymunk scenes -> results and logs.

A batch of tests is one pymunk space (:mod:`.scene`) stepped together, the coupling of every
scene advanced by one :meth:`Coupling.step` call per step; ``workers > 1`` splits the batch
over processes. Each test starts at the beginning of its record, ``pre_trigger_s`` before the
impact, with the drop mass where free fall from its drop height has brought it (so the record
needs no simulated fall of up to 1.1 s), and the coupling pre-twisted to its preload
(:mod:`.preload`).
"""
from __future__ import annotations

import math
import multiprocessing
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np
import pandas as pd

from droptower.errors import DroptowerError, expects
from droptower.limits import STEP_LIMIT, memory_limit_bytes, require_memory, require_steps
from droptower.io.droptower_log import write_log
from droptower.io.signals import DropSignals
from droptower.rheology import Coupling
from droptower.rig.config import RigConfig
from droptower.rig.impact_law import ImpactVelocities, first_period, impact_velocities, lever_tip_path
from droptower.rig.preload import Pretwist, pretwist
from droptower.rig.sensors import Channels, force_pulses, sample

if TYPE_CHECKING:
    from droptower.rig.scene import Contact

ENERGY_SAMPLE_S = 5e-4    # energies are sampled this often


@dataclass(frozen=True)
class DropTest:
    """One test condition (SI): the lever inertia, drop mass, height, preload; repeat and seed."""

    inertia_kgm2: float
    drop_mass_kg: float
    drop_height_m: float
    preload_nm: float = 0.0
    repeat: int = 0
    seed: int = 0


@dataclass
class DropResult:
    """One simulated drop test.

    time_s (N,) from ``-pre_trigger_s`` (impact near 0); angle_rad (N,) the lever's rotation
    from its rest position (positive in the impact direction); pretwist_rad the preload twist
    of the coupling at rest; screw_torque_nm the preload screw's torque; coupling_torque_nm (N,)
    the coupling's torque (preload included); drop_mass_m (N,) drop-mass position below the
    impact point. Energies (J, on ``energy_time_s``) as in :class:`~droptower.rig.scene.SceneRecord`.
    contact_impulse_ns (N,): the contacts' impulse on the drop mass in each sample (N*s; the
    contact force history the force sensor sees). contacts: every contact of the drop mass with
    the lever; predicted: docs/theory.md#impact closed forms.
    """

    rig: RigConfig
    coupling_name: str
    test: DropTest
    duration_s: float
    time_s: np.ndarray
    angle_rad: np.ndarray
    pretwist_rad: float
    screw_torque_nm: float
    coupling_torque_nm: np.ndarray
    drop_mass_m: np.ndarray
    contact_impulse_ns: np.ndarray
    energy_time_s: np.ndarray
    energy_j: dict[str, np.ndarray]
    contacts: list[Contact]
    predicted: ImpactVelocities
    warnings: list[str] = field(default_factory=list)

    # ---------------------------------------------------------------- derived
    @property
    def lever_tip_m(self) -> np.ndarray:
        """Where the lever meets the striker's line, below the impact point (m, positive down)."""
        return lever_tip_path(self.angle_rad, self.rig.lever_length_m)

    @property
    def impact_time_s(self) -> float:
        return self.contacts[0].start_s if self.contacts else math.nan

    @property
    def period_s(self) -> float:
        """The lever's first oscillation period: from the impact to the angle's second zero crossing."""
        t0 = self.impact_time_s
        if math.isnan(t0):
            return math.nan
        after = self.time_s >= t0
        return float(first_period(np.concatenate([[t0], self.time_s[after]]),
                                  np.concatenate([[0.0], self.angle_rad[after]])))

    @property
    def second_impact_time_s(self) -> float:
        """Time of the first contact after the impact (s from the impact), NaN if none."""
        return self.contacts[1].start_s - self.contacts[0].start_s if len(self.contacts) > 1 else math.nan

    @property
    def double_impact(self) -> bool:
        """A second contact within the lever's first oscillation period (Rapp et al. 2022, docs/theory.md#decay);
        without a complete period in the record, within the record."""
        period = self.period_s
        second = self.second_impact_time_s
        return bool(not math.isnan(second) and (math.isnan(period) or second <= period))

    @property
    def energy_balance_error(self) -> float:
        """max over the record of |E(t) - m1 g h| / (m1 g h), E = kinetic + potential + coupling
        stored + dissipated + contact losses - screw work (all changes since the start)."""
        e = self.energy_j
        total = e["kinetic"] + e["potential"] + e["stored"] + e["dissipated"] + e["contact_loss"] - e["screw_work"]
        supplied = self.test.drop_mass_kg * self.rig.gravity_m_per_s2 * self.test.drop_height_m
        return float(np.max(np.abs(total - supplied)) / supplied)

    def summary(self) -> str:
        """The test as text (what ``droptower simulate`` prints), as every ``summary()``; the
        figures are :meth:`to_dict`. Read as the dict it returned in release 0.1 (``["key"]``,
        ``.get``, ``.items``), it still answers with a DeprecationWarning for this release."""
        from droptower.deprecation import TextReport

        s = self.to_dict()
        t = self.test
        later = [1e3 * (c - s["impact_time_s"]) for c in s["contact_times_s"][1:]]
        lines = [
            f"{self.coupling_name} on {self.rig.name}: J = {t.inertia_kgm2:g} kg*m^2, m1 = {t.drop_mass_kg:g} kg, "
            f"h = {t.drop_height_m:g} m, preload {t.preload_nm:g} N*m (twist {s['pretwist_deg']:.3f} deg)",
            f"  after impact: drop mass {s['drop_mass_velocity_after_m_per_s']:+.4f} m/s "
            f"(impact law {s['predicted_drop_mass_velocity_after_m_per_s']:+.4f}), lever tip "
            f"{s['lever_tip_velocity_after_m_per_s']:+.4f} m/s (impact law "
            f"{s['predicted_lever_tip_velocity_after_m_per_s']:+.4f}), restitution {s['effective_restitution']:.4f}",
            f"  impact energy {s['impact_energy_j']:.4g} J, impulse {s['impact_impulse_n_s']:.4g} N*s",
            f"  {s['contacts']} contact(s) of drop mass and lever"
            + (f" (later ones at {', '.join(f'{x:.1f}' for x in later[:5])}{', ...' if len(later) > 5 else ''} ms "
               f"after the impact)" if later else "")
            + f"; double impact (a second contact within the first period, "
              f"{1e3 * s['first_period_s']:.1f} ms): {'yes' if s['double_impact'] else 'no'}",
            f"  max angle {s['max_angle_deg']:.3f} deg, max torque {s['max_torque_nm']:.1f} N*m, "
            f"first period {1e3 * s['first_period_s']:.2f} ms ({s['first_period_frequency_hz']:.2f} Hz), "
            f"energy balance error {100 * s['energy_balance_error_fraction']:.3f} %"]
        lines += [f"warning: {w}" for w in s["warnings"]]
        return TextReport("\n".join(lines), s, "DropResult")

    def to_dict(self) -> dict[str, Any]:
        """The figures of the test, every key with its unit (what ``droptower simulate`` prints as JSON)."""
        from droptower.rig.scene import Contact  # pymunk, loaded when a simulation runs

        first = self.contacts[0] if self.contacts else Contact(start_s=math.nan)
        L = self.rig.lever_length_m
        rate = first.lever_rate_after_rad_per_s
        period = self.period_s
        twist = self.pretwist_rad + self.angle_rad
        p = self.predicted
        return {
            "inertia_kgm2": self.test.inertia_kgm2, "drop_mass_kg": self.test.drop_mass_kg,
            "drop_height_m": self.test.drop_height_m, "preload_nm": self.test.preload_nm,
            "repeat": self.test.repeat, "seed": self.test.seed, "restitution": self.rig.restitution,
            "impact_velocity_m_per_s": first.approach_m_per_s,
            "drop_mass_velocity_after_m_per_s": first.drop_mass_after_m_per_s,
            "lever_tip_velocity_after_m_per_s": rate * L,
            "lever_rate_after_rad_per_s": rate,
            "predicted_drop_mass_velocity_after_m_per_s": float(p.drop_mass_after_m_per_s),
            "predicted_lever_tip_velocity_after_m_per_s": float(p.lever_tip_after_m_per_s),
            "effective_restitution": first.restitution,
            "impact_energy_j": 0.5 * self.test.inertia_kgm2 * rate ** 2,
            "predicted_impact_energy_j": float(p.impact_energy_j),
            "impact_time_s": self.impact_time_s,
            "impact_impulse_n_s": first.impulse_ns,
            "contacts": len(self.contacts),
            "contact_times_s": [c.start_s for c in self.contacts],
            "double_impact": self.double_impact,
            "second_impact_after_s": self.second_impact_time_s,
            # the first period from zero crossings, not a decay fit as extract's frequency_hz
            "first_period_s": period,
            "first_period_frequency_hz": 1.0 / period if period > 0 else math.nan,
            "pretwist_deg": math.degrees(self.pretwist_rad),
            "max_angle_deg": math.degrees(float(np.max(self.angle_rad))),
            "max_twist_deg": math.degrees(float(np.max(np.abs(twist)))),
            "max_torque_nm": float(np.max(np.abs(self.coupling_torque_nm))),
            "energy_balance_error_fraction": self.energy_balance_error,
            "warnings": list(self.warnings),
        }

    # ---------------------------------------------------------------- sensors and log
    def channels(self) -> Channels:
        """The test sampled by the rig's sensors, with the noise of ``test.seed``."""
        return sample(self.time_s, self.pretwist_rad + self.angle_rad, self.coupling_torque_nm, self.time_s,
                      self.contact_impulse_ns, self.rig.sensors, self.test.seed)

    def metadata(self) -> dict[str, Any]:
        """The log's metadata: what was tested, on which rig, and how it was sampled."""
        t, rig = self.test, self.rig
        return {
            "source": "droptower simulate", "rig": rig.name, "coupling": self.coupling_name,
            "inertia_kgm2": t.inertia_kgm2, "drop_mass_kg": t.drop_mass_kg, "drop_height_m": t.drop_height_m,
            "preload_nm": t.preload_nm, "repeat": t.repeat, "seed": t.seed, "restitution": rig.restitution,
            "sample_rate_hz": rig.sensors.sample_rate_hz, "pre_trigger_s": rig.sensors.pre_trigger_s,
            "lever_length_m": rig.lever_length_m, "laser_radius_m": rig.sensors.laser.radius_m,
            "pretwist_rad": self.pretwist_rad, "impact_time_s": self.impact_time_s,
            "contacts": len(self.contacts), "double_impact": self.double_impact,
        }

    def signals(self) -> DropSignals:
        """The sampled test with its metadata, as :func:`droptower.extract.extract` takes it (what
        reading the log :meth:`write_log` writes gives, without the file)."""
        ch = self.channels()
        return DropSignals(ch.time_s, ch.angle_rad, ch.torque_nm, ch.impact_force_n, metadata=self.metadata())

    def write_log(self, path: str | Path, compact: bool = False) -> Path:
        """Write the sampled test as a droptower log (``.csv`` or ``.parquet``; ``compact``: float32
        channels, compressed, see :func:`droptower.io.droptower_log.write_log`)."""
        ch = self.channels()
        return write_log(path, ch.time_s, ch.columns(), self.metadata(), compact=compact)


# -------------------------------------------------------------------- running
def as_tests(tests: Sequence[DropTest] | pd.DataFrame) -> list[DropTest]:
    """Test conditions from a list or from a DataFrame with the columns of :meth:`DOE.tests`."""
    if isinstance(tests, pd.DataFrame):
        cols = ["inertia_kgm2", "drop_mass_kg", "drop_height_m"]
        missing = [c for c in cols if c not in tests.columns]
        if missing:
            raise ValueError(f"test table lacks the columns {missing}")
        return [DropTest(float(r.inertia_kgm2), float(r.drop_mass_kg), float(r.drop_height_m),
                         float(getattr(r, "preload_nm", 0.0)), int(getattr(r, "repeat", 0)), int(getattr(r, "seed", 0)))
                for r in tests.itertuples(index=False)]
    return list(tests)


#: How far the first impact's separation/approach velocity ratio may differ from the rig's k.
RESTITUTION_TOLERANCE = 1e-3

#: float64 arrays per output sample and test: the scene's angle, torque, drop-mass path and
#: impulse grid, the sensors' channels and noise, the log's columns (an upper estimate)
ARRAYS_PER_SAMPLE = 16


def check_size(rig: RigConfig, coupling: Coupling, batch: int, duration_s: float, where: str = "duration") -> None:
    """Refuse ``batch`` drop tests of ``duration_s`` whose records would exceed the memory limit
    or whose simulation would take more than :data:`~droptower.limits.STEP_LIMIT` coupling steps
    (one line: the limit and the longest record that fits)."""
    fs = rig.sensors.sample_rate_hz
    per_second = batch * fs * 8.0 * ARRAYS_PER_SAMPLE
    n_samples = (rig.sensors.pre_trigger_s + duration_s) * fs
    longest = max(0.0, memory_limit_bytes() / per_second - rig.sensors.pre_trigger_s)
    what = f"{batch} drop test(s) of {duration_s:g} s at {fs:g} Hz"
    fewer = " or simulate fewer tests at once (a smaller `chunk_size`)" if batch > 1 else ""
    require_memory(batch * n_samples * (8.0 * ARRAYS_PER_SAMPLE) + 8.0 * batch * coupling.n_state, what,
                   f"record at most {longest:.3g} s after the impact{fewer}", where=where)
    steps = batch * n_samples * rig.simulation.steps_per_sample
    longest = STEP_LIMIT / (batch * fs * rig.simulation.steps_per_sample) - rig.sensors.pre_trigger_s
    require_steps(steps, what, f"record at most {longest:.3g} s after the impact{fewer}", where=where)


@expects(rig="droptower.rig.config.RigConfig", coupling="droptower.rheology.coupling.Coupling")
def simulate(rig: RigConfig, coupling: Coupling, tests: Sequence[DropTest] | pd.DataFrame,
             duration_s: float = 0.25, workers: int = 1) -> list[DropResult]:
    """Simulate drop tests on the virtual drop tower, all in one batch; results in order.

    Parameters
    ----------
    rig : RigConfig
        The drop tower (:func:`load_rig`).
    coupling : Coupling
        The coupling under test (:func:`droptower.rheology.load_coupling`).
    tests : sequence of DropTest, or DataFrame
        The tests: inertia (kg·m²), drop mass (kg), drop height (m), preload (N·m), repeat and
        seed each (a DataFrame with those columns, e.g. :meth:`DOE.tests`).
    duration_s : float, default 0.25
        Record length after the impact (s); the record starts the rig's ``pre_trigger_s`` before it.
    workers : int, default 1
        Processes to split the batch over.

    Returns
    -------
    list of DropResult
        One per test: the sampled signals (``write_log`` writes them as a log), the contacts and
        the energy balance.

    Raises
    ------
    DroptowerError
        A test the rig cannot run (out of its ranges) or a record beyond the memory limit.
    """
    tests = as_tests(tests)
    if not (math.isfinite(duration_s) and duration_s > 0):
        raise DroptowerError(f"record duration must be positive, got {duration_s} s", where="duration_s")
    for i, t in enumerate(tests):
        rig.check_test(t.inertia_kgm2, t.drop_mass_kg, t.drop_height_m, t.preload_nm, where=f"test {i + 1}")
    check_size(rig, coupling, len(tests), duration_s)
    inertia = np.array([t.inertia_kgm2 for t in tests])
    twist = pretwist(coupling, np.array([t.preload_nm for t in tests]), rig.simulation.preload_ramp_s,
                     rig.simulation.preload_hold_s)
    v1 = np.sqrt(2.0 * rig.gravity_m_per_s2 * np.array([t.drop_height_m for t in tests]))
    rig.check_time_step(coupling, inertia, twist.angle_rad, v1)
    if workers <= 1 or len(tests) < 2:
        return _run_batch(rig, coupling, tests, duration_s, twist)
    chunks = np.array_split(np.arange(len(tests)), min(workers, len(tests)))
    # forked workers only step the coupling (serial kernels, one thread): the preload, which may
    # spread a large batch over threads, ran above (a forked process makes its own threads if needed)
    with ProcessPoolExecutor(max_workers=len(chunks), mp_context=multiprocessing.get_context("fork")) as pool:
        parts = pool.map(_run_batch, [rig] * len(chunks), [coupling] * len(chunks),
                         [[tests[i] for i in c] for c in chunks], [duration_s] * len(chunks),
                         [twist.take(c) for c in chunks])
        return [r for part in parts for r in part]


def _run_batch(rig: RigConfig, coupling: Coupling, tests: list[DropTest], duration_s: float,
               twist: Pretwist, fly_between_contacts: bool = True) -> list[DropResult]:
    """The tests in one scene batch (``fly_between_contacts``: see :meth:`DropTowerScenes.run`)."""
    from droptower.rig.scene import DropTowerScenes  # pymunk: imported by the simulation only
    g = rig.gravity_m_per_s2
    inertia = np.array([t.inertia_kgm2 for t in tests])
    mass = np.array([t.drop_mass_kg for t in tests])
    height = np.array([t.drop_height_m for t in tests])
    predicted = impact_velocities(mass, inertia, rig.lever_length_m, height, rig.restitution, g)
    fs = rig.sensors.sample_rate_hz
    t_pre = rig.sensors.pre_trigger_s
    n_samples = int(round((t_pre + duration_s) * fs))
    v1 = predicted.impact_m_per_s
    v_start = v1 - g * t_pre  # free fall from the drop height reaches the impact point at t = 0
    gap = v_start * t_pre + 0.5 * g * t_pre ** 2
    scenes = DropTowerScenes(inertia_kgm2=inertia, drop_mass_kg=mass, gap_m=gap, start_velocity_m_per_s=v_start,
                             lever_length_m=rig.lever_length_m, restitution=rig.restitution,
                             striker_radius_m=rig.simulation.striker_radius_m, gravity_m_per_s2=g, dt_s=rig.dt_s,
                             solver_iterations=rig.simulation.solver_iterations, t0_s=-t_pre)
    energy_every = max(1, int(round(ENERGY_SAMPLE_S * fs)))
    rec = scenes.run(coupling, twist.state, twist.angle_rad, twist.torque_nm, n_samples,
                     rig.simulation.steps_per_sample, energy_every, fly_between_contacts)
    results = []
    for i, test in enumerate(tests):
        pred = ImpactVelocities(**{k: np.asarray(v)[i] for k, v in vars(predicted).items()})
        energy = {"kinetic": rec.kinetic_j[i], "potential": rec.potential_j[i], "stored": rec.stored_j[i],
                  "dissipated": rec.dissipated_j[i], "screw_work": rec.screw_work_j[i],
                  "contact_loss": rec.contact_loss_j[i]}
        result = DropResult(rig=rig, coupling_name=coupling.name, test=test, duration_s=duration_s,
                            time_s=rec.time_s, angle_rad=rec.angle_rad[i], pretwist_rad=float(twist.angle_rad[i]),
                            screw_torque_nm=float(twist.torque_nm[i]), coupling_torque_nm=rec.coupling_torque_nm[i],
                            drop_mass_m=rec.drop_mass_m[i], contact_impulse_ns=rec.contact_impulse_ns[i],
                            energy_time_s=rec.energy_time_s, energy_j=energy,
                            contacts=rec.contacts[i], predicted=pred)
        result.warnings.extend(_warnings(result))
        results.append(result)
    return results


def _warnings(result: DropResult) -> list[str]:
    out = []
    rig = result.rig
    twist = np.max(np.abs(result.pretwist_rad + result.angle_rad))
    if twist > rig.coupling_limit_rad:
        out.append(f"twist {math.degrees(twist):.1f} deg exceeds the coupling limit {rig.coupling_limit_deg:g} deg")
    torque = np.max(np.abs(result.coupling_torque_nm))
    if torque > rig.sensors.torque.range_nm:
        out.append(f"torque {torque:.0f} N*m beyond the torque sensor's range {rig.sensors.torque.range_nm:g} N*m")
    force = np.max(force_pulses(result.time_s, result.time_s, result.contact_impulse_ns,
                                rig.sensors.impact_force.contact_duration_s))
    if force > rig.sensors.impact_force.range_n:
        out.append(f"impact force {force:.0f} N beyond the force sensor's range {rig.sensors.impact_force.range_n:g} N")
    if not result.contacts:
        out.append("the drop mass never hit the lever within the record")
    elif abs(result.contacts[0].restitution - rig.restitution) > RESTITUTION_TOLERANCE:
        # too few solver passes leave the impulse unconverged: the impact is softer or harder than k
        out.append(f"the impact's realised restitution {result.contacts[0].restitution:.4f} differs from k = "
                   f"{rig.restitution:g} by more than {RESTITUTION_TOLERANCE:g}: raise simulation.solver_iterations "
                   f"(now {rig.simulation.solver_iterations})")
    if result.double_impact:
        out.append(f"double impact {1e3 * result.second_impact_time_s:.2f} ms after the impact")
    return out
