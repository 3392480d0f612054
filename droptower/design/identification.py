"""Drops that identify a model's parameters best: a locally D-optimal design.

Identifying a model from drop tests (:mod:`droptower.identify.dropfit`) is least squares on
the free decays; for white sensor noise its parameter covariance is the inverse of the Fisher
information F = sum over drops of S_i' S_i / sigma^2, with S_i the sensitivity of drop i's
predicted angle (and torque) to the parameters (each as its logarithm: relative changes). A
D-optimal design takes the N drops (repeats allowed) that maximise det F (Atkinson & Donev):
the smallest joint confidence region. The sensitivities are computed at the parameters the
coupling under test implies (a *locally* optimal design: the best guess is the coupling file
itself), for every candidate drop of the rig in one batched simulation of the core
(the nominal set and one forward step per parameter, all drops, one call).

Selection: greedy forward choice, then Fedorov exchange (swap a chosen drop for a candidate
while det F grows), which reaches the optimum of such small problems or comes close.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from droptower.design.choose import contiguous_feasible, predict_candidates
from droptower.design.coverage import Target
from droptower.deprecation import renamed_keywords
from droptower.errors import DroptowerError
from droptower.identify.droplogs import DropDecay
from droptower.identify.dropfit import DropFitSettings, DropProblem, drop_scale, identify_drops
from droptower.identify.families import family_class
from droptower.rheology import Coupling
from droptower.rig.config import RigConfig

#: Periods of each decay compared, as :func:`~droptower.identify.dropfit.identify_drops` reads logs.
COMPARED_PERIODS = 3.0
#: The sensitivities are evaluated on every this-many-th sample of the rig (a decay's
#: information is carried by its shape; the count is scaled back to the rig's rate).
SAMPLE_STRIDE = 4
#: Forward-difference step in each parameter's logarithm.
FD_STEP = 1e-4
#: Exchange passes of the Fedorov algorithm.
EXCHANGE_PASSES = 5


@dataclass
class IdentificationDesign:
    """conditions: the chosen drops (one row per distinct drop, ``repeats`` its multiplicity),
    with the planner's prediction; parameters: per model parameter its nominal value and the
    predicted standard error (value units and relative) of the design, and of ``reference`` if
    given; log_det: log det F of the design; family: the drop-test family identified (``model``
    in release 0.1: deprecated)."""

    family: str
    conditions: pd.DataFrame
    parameters: pd.DataFrame
    log_det: float
    rig_name: str = ""
    coupling_name: str = ""
    plan_file: str | None = None
    sheet_file: str | None = None

    @property
    def model(self) -> str:
        """Deprecated: :attr:`family` (removed in the next release)."""
        from droptower.deprecation import warn_deprecated

        warn_deprecated("IdentificationDesign.model", "IdentificationDesign.family")
        return self.family

    @property
    def n_tests(self) -> int:
        """The number of drops (repeats included)."""
        return int(self.conditions["repeats"].sum())

    def write(self, out: str | Path, sheet: str | Path | None = None, seed: int = 0) -> Path:
        """Write the plan TOML ``out`` and, if given, the lab's run ``sheet`` (as
        :meth:`~droptower.design.choose.Design.write`); returns the plan's path."""
        from droptower.design.outputs import write_plan

        return write_plan(self, out, f"designed by droptower for identifying {self.family}: "
                                     f"{self.n_tests} drops (D-optimal)", sheet, seed)

    def to_frame(self) -> pd.DataFrame:
        """The chosen drops, one row per distinct drop (``repeats`` its multiplicity)."""
        return self.conditions.copy()

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: tests, conditions, the parameters' predicted standard errors, log det F, files."""
        from droptower.design.outputs import condition_records

        params = {r.parameter: {"value": r.value, "stderr": r.stderr, "relative_stderr": r.relative_stderr}
                  for r in self.parameters.itertuples()}
        return {"tests": self.n_tests, "conditions": condition_records(self.conditions), "family": self.family,
                "predicted_stderr": params, "log_det_information": self.log_det, "plan_file": self.plan_file,
                "sheet_file": self.sheet_file}

    def summary(self) -> str:
        """The chosen drops and the parameters' predicted standard errors, as text."""
        from droptower.design.outputs import condition_table, wide_floats

        with wide_floats():
            errors = self.parameters.to_string(index=False)
        return "\n".join([f"{self.n_tests} drops that identify {self.family} best (D-optimal) on rig {self.rig_name} "
                          f"with {self.coupling_name}:", condition_table(self.conditions),
                          "predicted standard errors (sensor noise of the rig, white):", errors])

    def __repr__(self) -> str:
        return f"<IdentificationDesign: {self.n_tests} drops that identify {self.family} best (D-optimal)>"

    def _repr_html_(self) -> str:
        return f"<p>{repr(self).strip('<>')}</p>" + self.parameters.to_html(index=False)


def _decays(rig: RigConfig, cands: pd.DataFrame) -> list[DropDecay]:
    """Placeholder decays of the candidate drops (their times, inertia and impact rate; the
    angles are simulated, not measured)."""
    out = []
    dt = SAMPLE_STRIDE / rig.sensors.sample_rate_hz
    for i, r in enumerate(cands.itertuples(index=False)):
        t = np.arange(1, int(COMPARED_PERIODS * float(r.first_period_s) / dt) + 1) * dt
        out.append(DropDecay(f"candidate {i}", t, np.zeros_like(t), None, float(r.inertia_kgm2),
                             float(r.lever_rate_after_rad_per_s), "prediction", float(r.frequency_hz),
                             math.radians(float(r.first_peak_deg)), dt))
    return out


def fisher_per_drop(problem: DropProblem, values: np.ndarray, free: np.ndarray, rig: RigConfig,
                    decays: list[DropDecay]) -> np.ndarray:
    """(T, p, p) Fisher information of each drop for the free parameters' logarithms, with the
    rig's sensor noise (laser noise over its radius for the angle; the torque sensor's noise)
    at the rig's sample rate."""
    params = problem.family.parameters
    idx = np.flatnonzero(free)
    rows = np.repeat(values[None], idx.size + 1, axis=0)
    for k, j in enumerate(idx):
        z = params[j].to_z(values[j]) + FD_STEP
        rows[k + 1, j] = params[j].to_value(z)
    a, q = problem.simulate(rows)
    if not np.all(np.isfinite(a[0])):
        raise DroptowerError("the model does not simulate every candidate drop at its nominal parameters")
    mask = problem.mask[None]  # each drop's own samples (the arrays are padded to the longest)
    sa = np.where(mask, a[1:] - a[0][None], 0.0) / FD_STEP  # (p, T, N)
    sq = np.where(mask, q[1:] - q[0][None], 0.0) / FD_STEP
    sigma_a = max(rig.sensors.laser.noise_m / rig.sensors.laser.radius_m, 1e-9)
    sigma_q = max(rig.sensors.torque.noise_nm, 1e-6)
    # samples of the rig per evaluated sample: the information scales with the sample count
    per = np.array([d.dt_s * rig.sensors.sample_rate_hz for d in decays])
    fa = np.einsum("itn,jtn->tij", sa, sa) / sigma_a**2
    fq = np.einsum("itn,jtn->tij", sq, sq) / sigma_q**2
    return (fa + fq) * per[:, None, None]


def _log_det(f: np.ndarray) -> float:
    sign, value = np.linalg.slogdet(f)
    return float(value) if sign > 0 else -math.inf


def d_optimal(info: np.ndarray, n: int) -> list[int]:
    """Indices (with repeats) of ``n`` drops maximising log det of their summed information
    ``info`` (T, p, p): greedy forward choice, then Fedorov exchange."""
    t, p, _ = info.shape
    ridge = 1e-10 * np.trace(info.sum(axis=0)) / p * np.eye(p)  # fewer drops than parameters: still ranked
    chosen: list[int] = []
    total = ridge.copy()
    for _ in range(n):
        scores = [_log_det(total + info[i]) for i in range(t)]
        best = int(np.argmax(scores))
        chosen.append(best)
        total = total + info[best]
    for _ in range(EXCHANGE_PASSES):
        improved = False
        for k in range(n):
            base = total - info[chosen[k]]
            scores = [_log_det(base + info[i]) for i in range(t)]
            best = int(np.argmax(scores))
            if scores[best] > _log_det(total) + 1e-9:
                total = base + info[best]
                chosen[k] = best
                improved = True
        if not improved:
            break
    return sorted(chosen)


@renamed_keywords(model="family")
def design_for_identification(rig: RigConfig, coupling: Coupling, target: Target, family: str, n_tests: int,
                              *, options: dict | None = None, reference: pd.DataFrame | None = None,
                              candidates: pd.DataFrame | None = None) -> IdentificationDesign:
    """The ``n_tests`` drops within ``target`` that identify ``family`` best on ``coupling``.

    family: a drop-test family (``model`` in release 0.1: deprecated; ``template``: ``coupling``
    itself with its numbers as factors;
    others: first fitted to the coupling's predicted decays over the candidates, so the design
    is optimal where that fit says the parameters are); reference: another plan's conditions
    (columns ``inertia_kgm2``, ``drop_mass_kg``, ``drop_height_m``) whose predicted standard
    errors are reported beside the design's.
    """
    name = family  # the family's name; ``family`` below is the family bound to the decays' scale
    cands = predict_candidates(rig, coupling, (0.0,)) if candidates is None else candidates
    feasible = contiguous_feasible(cands)
    (a0, a1), (f0, f1) = target.amplitude_deg, target.frequency_hz
    pool = feasible[feasible["amplitude_deg"].between(a0, a1) & feasible["frequency_hz"].between(f0, f1)]
    if len(pool) < 2:
        raise DroptowerError(f"fewer than two possible drops of rig {rig.name} lie in the target "
                             f"{a0:g}-{a1:g} deg x {f0:g}-{f1:g} Hz", where="for_identification")
    pool = pool.reset_index(drop=True)
    if reference is not None:
        from droptower.rig.predictions import plan

        ref = plan(rig, coupling, reference.assign(case="reference", preload_nm=0.0, repeats=1))
        pool = pd.concat([pool, ref], ignore_index=True)
    decays = _decays(rig, pool)
    settings = DropFitSettings(conditioning=(rig.simulation.preload_ramp_s, rig.simulation.preload_hold_s))
    truth = family_class("template")(drop_scale(decays), {"template": coupling})
    truth_problem = DropProblem(truth, decays, settings)
    angle, torque = truth_problem.simulate(truth.guess()[None])
    measured = [DropDecay(d.name, d.time_s, angle[0, i, :d.time_s.size], torque[0, i, :d.time_s.size],
                          d.inertia_kgm2, d.rate0_rad_per_s, d.rate_source, d.frequency_hz, d.amplitude_rad, d.dt_s)
                for i, d in enumerate(decays)]
    opts = dict(options or {})
    if name == "template":
        opts.setdefault("template", coupling)
        family = family_class(name)(drop_scale(measured), opts)
        values = family.guess()
    else:
        fit = identify_drops(name, measured, settings=settings, options=opts)
        family, values = fit.family_model, fit.params.vector()
    problem = DropProblem(family, measured, settings)
    free = np.array([p.name != "p" for p in family.parameters])
    info = fisher_per_drop(problem, values, free, rig, measured)
    n_pool = len(pool) - (len(reference) if reference is not None else 0)
    chosen = d_optimal(info[:n_pool], n_tests)
    total = info[chosen].sum(axis=0)
    names = [p.name for p, f in zip(family.parameters, free) if f]
    vals = values[free]
    params = family.parameters

    def std_of(f: np.ndarray) -> np.ndarray:
        sz = np.sqrt(np.diag(np.linalg.pinv(f)))
        return np.array([sz[k] * params[j].dvalue_dz(values[j]) for k, j in enumerate(np.flatnonzero(free))])

    table = pd.DataFrame({"parameter": names, "value": vals, "stderr": std_of(total)})
    table["relative_stderr"] = table["stderr"] / np.abs(table["value"])
    if reference is not None:
        ref_std = std_of(info[n_pool:].sum(axis=0))
        table["reference_stderr"] = ref_std
        table["reference_relative_stderr"] = ref_std / np.abs(table["value"])
    counts = pd.Series(chosen).value_counts().sort_index()
    cond = pool.iloc[counts.index].copy()
    cond["repeats"] = counts.to_numpy()
    return IdentificationDesign(name, cond.reset_index(drop=True), table, _log_det(total))
