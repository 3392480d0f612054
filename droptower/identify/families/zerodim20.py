"""The zero-dimensional model paper's lookup-table model with the Mullins filter (section 4, eq. 3): family and strategy.

The six-parameter fit mapped exactly onto the tables and the Mullins filter, then all 20
parameters jointly.
"""
from __future__ import annotations

import math

import numpy as np

from droptower.identify.data import DataScale, Segment
from droptower.identify.families.base import COMMON_OPTIONS, Family, stiffness_parameter
from droptower.identify.families.stages import Setup, result_of, setup
from droptower.identify.families.zerodim6 import ZeroDim6, staged_fit
from droptower.identify.fit import FitResult, FitVariable, clip_to_bounds
from droptower.identify.result import Identification
from droptower.rheology import parse_coupling

#: A lookup-table value may move by this factor from the six-parameter start.
TABLE_RANGE = 3.0

FAR = 1e3


class ZeroDim20(Family):
    """The zero-dimensional model paper's lookup-table model with the Mullins filter, 20 parameters.

    Mullins filter (eq. 3): slow stiffness, fast minus slow stiffness, time constant tau (3);
    a Maxwell branch whose spring stiffness is a 9-point table over its deformation
    (breakpoints evenly over +-the largest amplitude of the data) and whose damping is an
    8-point table over its rate (0 .. the largest rate of the data): 9 + 8 = 17. The zero-dimensional model paper
    reduced its 45 lookup values to 20; this is one such choice. Beyond their breakpoints the
    tables hold their end values. Within them it contains the six-parameter model exactly
    (tables linear in |e| and constant), so it starts from that fit.

    Every candidate is admissible by construction: the core refuses a table whose force
    (coefficient linear between breakpoints, times the deformation or rate) falls anywhere,
    which holds iff from one breakpoint (distance a from 0) outwards to the next (b) the
    coefficient changes by a ratio of at least max(b / (2b - a), (2a - b) / a). The parameters
    are the table values at 0 (k3 at e = 0, c3 at v = 0) and, outwards, the excess q > 0 of each
    ratio over its minimum (``*_excess``); the tables are reported as derived values.
    """

    kind = "zerodim20"
    title = "zero-dimensional lookup-table model with Mullins filter (20 parameters)"
    source = "the zero-dimensional model paper (zero-dimensional model), section 4, eq. 3"
    OPTIONS = {"deformation_max_rad": 0.0, "rate_max_rad_per_s": 0.0}
    N_STIFF = 9
    N_DAMP = 8

    def _parameters(self):
        s = self.scale
        self.set_breakpoints(float(self.options["deformation_max_rad"]) or s.amplitude_rad,
                             float(self.options["rate_max_rad_per_s"]) or s.rate_rad_per_s)
        c_hi = 1e3 * s.stiffness_nm_per_rad
        half = self.N_STIFF // 2
        excess = ([f"k3_excess_to_minus_e{m}" for m in range(half, 0, -1)]
                  + [f"k3_excess_to_e{m}" for m in range(1, half + 1)])
        return ([stiffness_parameter("k_slow_nm_per_rad", s), stiffness_parameter("k_fast_minus_slow_nm_per_rad", s),
                 FitVariable("tau_mullins_s", 1e-3, 1e4), stiffness_parameter("k3_at_0_nm_per_rad", s)]
                + [FitVariable(n, 1e-6, 1e3) for n in excess]
                + [FitVariable("c3_at_0_nms_per_rad", 1e-9 * c_hi, c_hi)]
                + [FitVariable(f"c3_excess_to_v{i}", 1e-6, 1e3) for i in range(1, self.N_DAMP)])

    def set_breakpoints(self, deformation_max_rad: float, rate_max_rad_per_s: float) -> None:
        """Table breakpoints: stiffness over +-deformation_max (the branch spring's own
        deformation), damping over 0 .. rate_max (its dashpot's rate)."""
        self.deformation_rad = np.linspace(-deformation_max_rad, deformation_max_rad, self.N_STIFF)
        self.rate_rad_per_s = np.linspace(0.0, rate_max_rad_per_s, self.N_DAMP)

    def guess(self):
        return self.from_zerodim6(ZeroDim6(self.scale).guess())

    def from_tables(self, head: np.ndarray, ks: np.ndarray, cs: np.ndarray) -> np.ndarray:
        """Parameters of the Mullins part ``head`` (3) and admissible tables ``ks`` (9), ``cs``
        (8) (the inverse of :meth:`tables`)."""
        half = self.N_STIFF // 2
        e = np.abs(self.deformation_rad[half:])
        left = _excess(ks[half::-1], e)[::-1]  # outwards to the left, stored from e_-4 inwards
        right = _excess(ks[half:], e)
        return np.concatenate([head, [ks[half]], left, right, [cs[0]], _excess(cs, self.rate_rad_per_s)])

    def tables(self, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The stiffness (N*m/rad) and damping (N*m*s/rad) tables of parameter vector ``v``."""
        half = self.N_STIFF // 2
        e = np.abs(self.deformation_rad[half:])
        q = np.asarray(v[4:4 + 2 * half])
        left = _outwards(v[3], q[:half][::-1], e)
        right = _outwards(v[3], q[half:], e)
        ks = np.concatenate([left[::-1], right[1:]])
        cs = _outwards(v[4 + 2 * half], np.asarray(v[5 + 2 * half:]), self.rate_rad_per_s)
        return ks, cs

    def from_zerodim6(self, v6: np.ndarray) -> np.ndarray:
        """The 20 parameters that reproduce a six-parameter model exactly."""
        k1, k2, tau2, k3, gain, tau3 = v6
        return self.from_tables(np.array([k1, k2, tau2]), k3 + gain * np.abs(self.deformation_rad),
                                np.full(self.N_DAMP, k3 * tau3))

    def derived(self, v):
        ks, cs = self.tables(v)
        return {**{f"k3_{i + 1}_nm_per_rad": float(k) for i, k in enumerate(ks)},
                **{f"c3_{i + 1}_nms_per_rad": float(c) for i, c in enumerate(cs)}}

    def elements(self, v):
        k_slow, dk, tau = v[:3]
        ks, cs = self.tables(v)
        # beyond its breakpoints a table holds its end value (one more point far out): the
        # core extrapolates linearly, which could turn a falling damping table negative on
        # data faster than the fitting data (a lookup table's usual end clamp)
        e, far = self.deformation_rad, FAR * self.deformation_rad[-1]
        return [{"kind": "mullins", "name": "Mullins filter", "tau": tau, "slow_stiffness": k_slow,
                 "fast_stiffness": k_slow + dk},
                {"kind": "variable_maxwell", "name": "K3-C3 tables",
                 "stiffness_table": {"x": [-far, *e.tolist(), far], "y": [ks[0], *ks.tolist(), ks[-1]]},
                 "damping_table": {"x": [*self.rate_rad_per_s.tolist(), FAR * self.rate_rad_per_s[-1]],
                                   "y": [*cs.tolist(), cs[-1]]}}]


def _min_ratio(d: np.ndarray) -> np.ndarray:
    """Smallest coefficient ratio from breakpoint d[j] to d[j + 1] (distances from 0, rising)
    that keeps coefficient * distance rising on the segment (the coefficient linear on it)."""
    a, b = d[:-1], d[1:]
    second = np.divide(2 * a - b, a, out=np.zeros_like(a), where=a > 0)
    return np.maximum(b / (2 * b - a), second)


def _outwards(c0: float, excess: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Coefficients at the distances ``d`` from c0 at d[0] = 0 and the ratios' excesses."""
    return float(c0) * np.concatenate([[1.0], np.cumprod(_min_ratio(d) + excess)])


def _excess(c: np.ndarray, d: np.ndarray) -> np.ndarray:
    """The inverse of :func:`_outwards`: each ratio's excess over its minimum."""
    return c[1:] / c[:-1] - _min_ratio(d)


def branch_ranges(v6: np.ndarray, segments: list[Segment]) -> tuple[float, float]:
    """Largest deformation of the K3 spring and largest rate of the C3 dashpot (rad, rad/s)
    that the six-parameter model ``v6`` visits on ``segments``: where the zero-dimensional model paper's lookup tables
    of the same branch need their breakpoints."""
    k3, gain, tau3 = v6[3], v6[4], v6[5]
    six = ZeroDim6(DataScale.of(segments))
    branch = parse_coupling({"element": [six.elements(v6)[2]]})  # the variable Maxwell branch alone
    t3 = np.concatenate([np.abs(branch.respond(seg.angle_rad, seg.dt_s)) for seg in segments])
    peak = float(t3.max())
    e_max = 2 * peak / (k3 + math.sqrt(k3 * k3 + 4 * gain * peak)) if gain > 0 else peak / k3
    return e_max, peak / (k3 * tau3)


def identify_zerodim20(s: Setup, segments: list[Segment], start: float, previous: dict | None = None,
                       **_) -> Identification:
    fam: ZeroDim20 = s.family  # type: ignore[assignment]
    x = s.x0.copy()
    stages: list[FitResult] = []
    if not s.given.all():
        six = (previous or {}).get("zerodim6")
        if six is None:
            opts = {k: v for k, v in fam.options.items() if k in COMMON_OPTIONS}
            s6 = setup(ZeroDim6, segments, options=opts)
            v6, stages, _ = staged_fit(s6, segments)
        else:
            v6 = np.array(list(six.parameters.values()))
        e_max, v_max = branch_ranges(v6, segments)
        fam.set_breakpoints(float(fam.options["deformation_max_rad"]) or e_max,
                            float(fam.options["rate_max_rad_per_s"]) or v_max)
        for i, (name, value) in enumerate(zip(fam.names, fam.from_zerodim6(v6))):
            s.set_estimate(x, name, value)
            p = fam.parameters[i]
            if i >= 3 and not s.bounded[i]:
                # the zero-dimensional model paper: "sound constraints" - a table value (or force rise between
                # breakpoints) stays within a factor of TABLE_RANGE of the six-parameter start, so
                # a breakpoint the data hardly reach cannot run off (and spoil the model just
                # beyond the fitting data)
                fam.parameters[i] = FitVariable(p.name, max(p.lower, x[i] / TABLE_RANGE), min(p.upper, x[i] * TABLE_RANGE),
                                              p.log, p.scale)
                x[i] = clip_to_bounds([fam.parameters[i]], [x[i]])[0]
    r = s.fit(segments, x, None, "joint (20 parameters)")
    extra = {"deformation_breakpoints_rad": fam.deformation_rad.tolist(),
             "rate_breakpoints_rad_per_s": fam.rate_rad_per_s.tolist()}
    return result_of(s, segments, r.values.copy(), stages + [r], start, extra=extra)


FAMILY = ZeroDim20
strategy = identify_zerodim20
