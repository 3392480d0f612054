"""An honest verdict on an identification: its error against the data's own noise floor.

``converged`` says only that the optimiser met its tolerance: a local minimum converges too.
The verdict compares the fit error with what the data allow (the noise floor, estimated
without a model: :mod:`.noise`) and looks at the parameters:

- ``"good fit"``: the RMS error is at most :data:`NOISE_RATIO` times the allowance and no
  parameter sits on a bound. The allowance is what a fit at the truth can reach on these
  records: the noise floor and, in quadrature, the simulation's own accuracy, which the
  callers measure on the fitted model itself: its integration error at the data's step (the
  model re-simulated on half the step, twice the RMS change: Richardson, first order) and for
  drop tests the re-simulation's accuracy against the rig (docs/theory.md#verdict). So a fit
  at the truth is never poor for the step's sake (an elastoslide of high p in a fast decay has
  that error far above the sensor noise), and a clearly-off fit (K' 3 %, a relaxation time
  10x) still leaves tens of times the allowance. Without a noise estimate the error is not
  judged;
- ``"poor fit"`` otherwise, with the reasons: the model misses structure in the data (a
  local minimum, or a family that cannot represent the coupling), or a parameter ended on a
  bound (the optimum lies outside the box, or the parameter is not supported by the data).
  A linear parameter on a lower bound of 0 is a term switched off, not a bound hit.

A poor fit is exit code :data:`EXIT_POOR_FIT` of ``identify`` and ``compare-models`` unless it is accepted
(``accept_poor``, e.g. :meth:`~droptower.identify.ranking.Comparison.exit_code`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from droptower.units import printed_unit

#: A fit error above this multiple of the noise allowance is a poor fit.
NOISE_RATIO = 2.0
#: The re-simulation's own accuracy against the rig, relative to a test's amplitude (tested:
#: within 0.2 %; the integration step's first-order part): the drop-test verdict's allowance beside the noise.
RESIMULATION_ACCURACY = 1e-3
#: Exit code of ``identify`` / ``compare-models`` on a poor fit (2: bad input or no convergence).
EXIT_POOR_FIT = 3
GOOD, POOR = "good fit", "poor fit"


@dataclass(frozen=True)
class Verdict:
    """verdict: ``"good fit"`` or ``"poor fit"``; reasons: why it is poor; error_over_noise:
    the RMS fit error over the noise allowance; noise_floor: the data's noise (unit in
    ``unit``); allowance: the noise floor with the simulation's accuracy added."""

    verdict: str
    error_over_noise: float
    noise_floor: float
    allowance: float
    unit: str
    reasons: list[str] = field(default_factory=list)

    @property
    def poor(self) -> bool:
        return self.verdict == POOR

    def as_dict(self) -> dict[str, Any]:
        """Deprecated: :meth:`to_dict` (removed in the next release)."""
        from droptower.identify.result import deprecated

        deprecated("Verdict.as_dict()", "Verdict.to_dict()")
        return self.to_dict()

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: the verdict, its reasons, the error over the allowance, the noise floor and
        the allowance (their unit in their names)."""
        return {"verdict": self.verdict, "reasons": list(self.reasons), "error_over_noise": self.error_over_noise,
                f"noise_floor_{self.unit}": self.noise_floor, f"noise_allowance_{self.unit}": self.allowance,
                "noise_ratio_limit": NOISE_RATIO}

    def text(self) -> str:
        head = (f"verdict: {self.verdict} (fit error {self.error_over_noise:.2f} x the noise allowance "
                f"{self.allowance:.3g} {printed_unit(self.unit)}; limit {NOISE_RATIO:g})")
        return head + "".join(f"\n  - {r}" for r in self.reasons)


def bound_hits(parameters: list[Any], at_bounds: list[str]) -> list[str]:
    """Parameters on a bound that count against a fit (not a linear term switched off at 0)."""
    by_name = {p.name: p for p in parameters}
    out = []
    for name in at_bounds:
        p = by_name.get(name)
        if p is not None and not p.log and p.lower == 0.0:
            continue
        out.append(name)
    return out


def judge(error_rms: float, noise_floor: float, unit: str, at_bound: list[str], *,
          accuracy: float = 0.0, converged: bool = True) -> Verdict:
    """The verdict on a fit of RMS error ``error_rms`` to data of noise ``noise_floor`` (same
    unit ``unit``); ``accuracy``: the simulation's own error, added to the noise in quadrature;
    ``at_bound``: parameters on a bound that count (:func:`bound_hits`)."""
    allowance = math.hypot(noise_floor, accuracy) if math.isfinite(noise_floor) else accuracy
    # no noise estimate (records too short to smooth, no pre-trigger part): the error is not judged
    ratio = error_rms / allowance if allowance > 0 else math.nan
    reasons = []
    if ratio > NOISE_RATIO:
        reasons.append(f"the fit error is {ratio:.3g} x the noise allowance (limit {NOISE_RATIO:g}): the model misses "
                       "structure in the data (a local minimum, or a family that cannot represent this coupling)")
    if at_bound:
        reasons.append(f"parameter(s) on a bound: {', '.join(at_bound)} (the best fit lies outside the bounds, or the "
                       "data do not support the parameter)")
    if not converged:
        reasons.append("the optimiser did not converge")
    return Verdict(POOR if reasons else GOOD, ratio, noise_floor, allowance, unit, reasons)


def step_error(fine: np.ndarray, coarse: np.ndarray) -> float:
    """The model's own integration error at its step: twice the RMS change of its output
    (``coarse``, on the step; ``fine``, on half of it) over the compared samples (Richardson,
    first order: docs/theory.md#verdict), in their unit; 0 where there is nothing to compare or
    the half-step run was refused (not finite)."""
    fine, coarse = np.asarray(fine, float), np.asarray(coarse, float)
    error = 2.0 * float(np.sqrt(np.mean((fine - coarse) ** 2))) if fine.size else 0.0
    return error if math.isfinite(error) else 0.0


def servo_verdict(result: Any, noise: Any, parameters: list[Any],
                  idle: list[str] | None = None) -> Verdict:
    """The verdict on a fit to servo records (an :class:`~droptower.identify.result.Identification`
    with the last stage's :class:`~droptower.identify.fit.FitResult`): its RMS torque error
    against the records' noise floor (``noise``, :class:`~droptower.identify.noise.NoiseFloor`, N*m), with the model's discretisation error at the sample step (the last stage's
    ``step_error_nm``) added in quadrature; ``idle``: parameters of a switched-off part, whose
    bounds are not bound hits."""
    step = float(result.stages[-1].step_error_nm) if result.stages else 0.0
    hits = bound_hits(parameters, [n for n in result.at_bounds if n not in set(idle or ())])
    return judge(result.fit_error.rmse_nm, noise.sigma, "nm", hits, accuracy=step, converged=result.converged)


def drop_verdict(problem: Any, values: np.ndarray, at_bound: list[str], converged: bool,
                 fine_angle: np.ndarray | None = None) -> tuple[Verdict, float, int]:
    """The verdict on a fit to drop tests (``problem``: the fitting tests,
    :class:`~droptower.identify.engine.problem.DropProblem`): its RMS angle error over the fitting tests (rad)
    against the allowance: the logs' pre-trigger noise, the re-simulation's accuracy against
    the rig (:data:`RESIMULATION_ACCURACY` of each test's amplitude) and the fitted model's own
    integration error at the logs' step, in quadrature; and the sum of squared angle errors
    (rad^2) over the compared samples and their number (the ranking's likelihood term).

    The integration error is what the re-simulation cannot reach at that step: the fitted
    model's angle re-simulated on half the step (``fine_angle`` (T, N), computed here when not
    given), twice the RMS change (Richardson, first order: docs/theory.md#verdict). A fit at
    the truth differs from the rig's logs by the noise and that error, so it is never judged
    poor for the step's sake; stiff rate laws (an elastoslide of high p at a fast decay) have
    it far above the noise."""
    a, _ = problem.simulate(values[None])
    if fine_angle is None:
        fine_angle = problem.simulate(values[None], 2 * problem.settings.substeps)[0][0]
    err = ((a[0] - problem.angle) ** 2)[problem.mask]
    noise = np.array([d.angle_noise_rad for d in problem.decays])
    counts = problem.mask.sum(axis=1)
    sigma = float(np.sqrt(np.sum(noise ** 2 * counts) / counts.sum()))
    resim = float(np.sqrt(np.sum((RESIMULATION_ACCURACY * np.array([d.amplitude_rad for d in problem.decays])) ** 2
                                 * counts) / counts.sum()))
    accuracy = math.hypot(resim, step_error(fine_angle[problem.mask], a[0][problem.mask]))
    verdict = judge(float(np.sqrt(np.mean(err))), sigma, "rad", at_bound, accuracy=accuracy, converged=converged)
    return verdict, float(np.sum(err)), int(err.size)
