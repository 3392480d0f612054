"""The zero-dimensional model paper's six-parameter model (section 5, Fig. 11): the family and its staged strategy.

K1 from static averages (in a periodic steady state the Maxwell branches carry no mean
torque, so mean torque / mean angle = K1), K2-C2 on slow ramps, K3-C3 on the sine sweeps,
then all six jointly from the better of those values and the first guess.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from droptower.identify.data import Segment
from droptower.identify.families.base import Family, stiffness_parameter
from droptower.identify.families.stages import STAGE_TOL, Setup, result_of, split_by_speed, static_stiffness, sweeps
from droptower.identify.fit import FitResult, FitVariable, batch_search
from droptower.identify.result import Identification

class ZeroDim6(Family):
    """The zero-dimensional model paper's six-parameter model: spring K1 || Maxwell(K2, C2) || Maxwell(K3(e), C3).

    K3 = k3 + gain |e| with e the branch spring's deformation (linear in the deformation, as
    in the zero-dimensional model paper, Fig. 11). The Maxwell branches are parameterised by relaxation times tau =
    C / K. Option ``tau_split_s`` > 0 confines the slow branch to relaxation times above it and
    the fast one below; the default 0 lets both span the whole range (both branches may act at
    the test frequencies; the staged start still gives K2-C2 the slow ramps and K3-C3 the sweeps).
    """

    kind = "zerodim6"
    title = "zero-dimensional six-parameter model: K1 || Maxwell(K2, C2) || Maxwell(K3 + gain |e|, C3)"
    source = "the zero-dimensional model paper (zero-dimensional model), section 5 / Fig. 11"
    OPTIONS = {"tau_split_s": 0.0}

    def _parameters(self):
        s, split = self.scale, float(self.options["tau_split_s"])
        slow, fast = ((split, 1e4), (1e-6, split)) if split > 0 else ((1e-6, 1e4), (1e-6, 1e4))
        return [stiffness_parameter("k1_nm_per_rad", s), stiffness_parameter("k2_nm_per_rad", s),
                FitVariable("tau2_s", *slow), stiffness_parameter("k3_nm_per_rad", s),
                FitVariable("k3_gain_nm_per_rad2", 0.0, 1e3 * s.stiffness_nm_per_rad / s.amplitude_rad, log=False,
                          scale=s.stiffness_nm_per_rad / s.amplitude_rad),
                FitVariable("tau3_s", *fast)]

    def guess(self):
        s = self.scale
        k = s.stiffness_nm_per_rad
        tau3 = 0.3 / (2 * np.pi * max(s.frequency_hz, 1e-3))
        tau2 = 10 * float(self.options["tau_split_s"]) or 1.0
        return np.array([0.5 * k, 0.3 * k, tau2, 0.5 * k, 0.0, tau3])

    def elements(self, v):
        k1, k2, tau2, k3, gain, tau3 = v
        return [{"kind": "spring", "name": "K1", "stiffness": k1},
                {"kind": "maxwell", "name": "K2-C2", "stiffness": k2, "damping": k2 * tau2},
                {"kind": "variable_maxwell", "name": "K3-C3", "stiffness": k3, "stiffness_gain": gain,
                 "damping": k3 * tau3}]

    def derived(self, v):
        k1, k2, tau2, k3, gain, tau3 = v
        return {"c2_nms_per_rad": k2 * tau2, "c3_nms_per_rad": k3 * tau3}


#: Where the lookup tables of ``zerodim20`` get their end-clamp points (times the last breakpoint).


def staged_fit(s: Setup, segments: list[Segment]) -> tuple[np.ndarray, list[FitResult], dict]:
    x = s.x0.copy()
    stages: list[FitResult] = []
    extra: dict[str, Any] = {}
    k1 = static_stiffness(segments)
    if k1 is not None and k1 > 0:
        s.set_estimate(x, "k1_nm_per_rad", k1)
        extra["k1_static_average_nm_per_rad"] = k1
    guess = x.copy()
    # the branch stages only give starting values for the joint fit: a looser tolerance
    slow, _ = split_by_speed(segments)
    if slow:
        names = ["k2_nm_per_rad", "tau2_s"] + ([] if k1 else ["k1_nm_per_rad"])
        r = s.fit(slow, x, names, "K2-C2 on slow ramps", tol=STAGE_TOL)
        x, stages = r.values.copy(), stages + [r]
    fast = sweeps(segments) or split_by_speed(segments)[1]
    if fast:
        r = s.fit(fast, x, ["k3_nm_per_rad", "k3_gain_nm_per_rad2", "tau3_s"], "K3-C3 on sweeps", tol=STAGE_TOL)
        x, stages = r.values.copy(), stages + [r]
    # the joint fit starts from the better of the staged values and the first guess (with the
    # static K1), both judged on all data in one batched call: a branch stage on part of the
    # data can end far from the joint optimum (the slow ramps excite a fast branch too, whose
    # guess is still wrong then), and a joint fit from there crawls along a valley until its
    # evaluation limit (measured: 140 steps and a poor fit, against 7 from the first guess)
    starts = np.array([x, guess])
    best = batch_search(s.family, segments, starts)[0]
    extra["joint_start"] = ("staged values", "first guess")[best]
    r = s.fit(segments, starts[best], None, "joint")
    return r.values.copy(), stages + [r], extra


def identify_zerodim6(s: Setup, segments: list[Segment], start: float, **_) -> Identification:
    x, stages, extra = staged_fit(s, segments)
    return result_of(s, segments, x, stages, start, extra=extra)


FAMILY = ZeroDim6
strategy = identify_zerodim6
