"""The elastoslide paper's distributed rate-dependent elastoslide model (eq. 13-25): family and strategy.

phi0, k, k0 from the initial loading curve through the loop tips at several amplitudes
(eq. 24), then v_r by a batched grid search, k, k0, v_r jointly, and p (odd) by walking the
candidates while the error falls. phi0 and v_r are identifiable only together (see
:func:`identify_elastoslide`).
"""
from __future__ import annotations

from typing import Any

import numpy as np
from scipy.optimize import least_squares

from droptower.errors import DroptowerError
from droptower.identify.cycles import turning_points
from droptower.identify.data import Segment
from droptower.identify.families.base import Family, stiffness_parameter
from droptower.identify.families.stages import Setup, result_of, steady_blocks
from droptower.identify.engine.problem import ServoProblem
from droptower.identify.engine.search import walk_choice
from droptower.identify.fit import Counter, FitResult, FitVariable, batch_search, clip_to_bounds
from droptower.identify.result import Identification

class ElastoslideFamily(Family):
    """The elastoslide paper's distributed rate-dependent elastoslide model: phi0, k, k0, v_r, p; with
    option ``maxwell_terms`` (0-2, default 0) also Maxwell branches (c_i, tau_i) in parallel
    for viscous frequency dependence (the structure of the ``rapp2022_nr60`` preset).

    p (odd integer) is chosen by a search over ``p_candidates``, never by the gradient
    optimiser; ``n`` is the number of discrete elastoslide elements.
    """

    kind = "elastoslide"
    title = "distributed rate-dependent elastoslide model (phi0, k, k0, v_r, p)"
    source = "the elastoslide paper (distributed rate-dependent elastoslide model), eq. 13-25"
    OPTIONS = {"n": 32, "p_candidates": [3, 5, 7, 9, 11], "maxwell_terms": 0}

    def _parameters(self):
        s = self.scale
        p = [int(v) for v in self.options["p_candidates"]]
        if not p or any(v < 1 or v % 2 == 0 for v in p):
            raise DroptowerError(f"p_candidates must be odd positive integers, got {p}")
        if int(self.options["maxwell_terms"]) not in (0, 1, 2):
            raise DroptowerError(f"option maxwell_terms must be 0, 1 or 2, got {self.options['maxwell_terms']}")
        maxwell = []
        for i in range(self.n_maxwell):
            maxwell += [stiffness_parameter(f"c{i + 1}_nm_per_rad", s, 1e-6, 1e2), FitVariable(f"tau{i + 1}_s", 1e-6, 1e3)]
        return [FitVariable("phi0_per_nm", 1e-4 / s.torque_nm, 1e4 / s.torque_nm),
                stiffness_parameter("k_nm_per_rad", s, 1e-3, 1e4), stiffness_parameter("k0_nm_per_rad", s, 1e-6, 1e2),
                FitVariable("v_r_rad_per_s", 1e-8, 1e4), FitVariable("p", 1.0, 99.0, log=False)] + maxwell

    @property
    def n_maxwell(self) -> int:
        return int(self.options["maxwell_terms"])

    def guess(self):
        s = self.scale
        k = s.stiffness_nm_per_rad
        w = 2 * np.pi * max(s.frequency_hz, 1e-3)
        maxwell = [[0.05 * k, 1.0 / w], [0.05 * k, 0.1 / w]][:self.n_maxwell]
        return np.array([1.0 / (0.5 * s.torque_nm), 2.0 * k, 0.3 * k, 0.1 * s.rate_rad_per_s,
                         float(self.options["p_candidates"][len(self.options["p_candidates"]) // 2])]
                        + [v for term in maxwell for v in term])

    def derived(self, v):
        phi0, k, k0, v_r, p = v[:5]
        # invariant under phi0 -> phi0 / a, v_r -> v_r a^p: the identifiable combination
        out = {"mean_slip_torque_at_1_rad_per_s_nm": float((1.0 / phi0) * (1.0 / v_r) ** (1.0 / p))}
        for i in range(self.n_maxwell):
            out[f"d{i + 1}_nms_per_rad"] = float(v[5 + 2 * i] * v[6 + 2 * i])
        return out

    def choices(self) -> dict[int, list[float]]:
        """p among its odd candidates (the option ``p_candidates``)."""
        return {self.names.index("p"): [float(v) for v in self.options["p_candidates"]]}

    def move_choice(self, v: np.ndarray, index: int, value: float, rate_rad_per_s: float) -> np.ndarray:
        """The odd exponent p moved to ``value`` with v_r moved along (:func:`rate_at_exponent`)."""
        if index != self.names.index("p"):
            return super().move_choice(v, index, value, rate_rad_per_s)
        return rate_at_exponent(v, self.names, int(value), rate_rad_per_s)

    def elements(self, v):
        phi0, k, k0, v_r, p = v[:5]
        out = [{"kind": "elastoslide", "phi0": phi0, "k": k, "k0": k0, "v_r": v_r, "p": int(round(p)),
                "n": int(self.options["n"])}]
        for i in range(self.n_maxwell):
            c, tau = v[5 + 2 * i], v[6 + 2 * i]
            out.append({"kind": "maxwell", "name": f"Maxwell {i + 1}", "stiffness": c, "damping": c * tau})
        return out


def loading_curve(amplitude_rad: np.ndarray, phi0: float, k: float, k0: float) -> np.ndarray:
    """The elastoslide paper, eq. 24: T = (1/phi0) (1 - exp(-k phi0 A)) + k0 A (N*m)."""
    return (1.0 - np.exp(-k * phi0 * amplitude_rad)) / phi0 + k0 * amplitude_rad


def loop_tips(segments: list[Segment]) -> tuple[np.ndarray, np.ndarray]:
    """The elastoslide paper, Fig. 10: points of the initial loading curve from steady loops.

    For every steady block: the half swing of the angle between its turning points, and half
    the difference of the torques AT those turning points (the loop tips, where the rate is
    zero), averaged over the block's cycles after the first. Returns (A rad, T N*m), sorted.
    """
    amps, torques = [], []
    for sb in steady_blocks(segments):
        seg = segments[sb.segment]
        x, y = seg.measured_angle, seg.measured_torque
        b = sb.block
        tp = turning_points(x[b.start:b.stop]) + b.start
        tp = tp[tp >= b.first_cycle_stop]
        if tp.size < 2 or not np.isfinite(y[tp]).all():
            continue
        dx = np.abs(np.diff(x[tp]))
        dy = np.abs(np.diff(y[tp]))
        amps.append(0.5 * float(np.mean(dx)))
        torques.append(0.5 * float(np.mean(dy)))
    order = np.argsort(amps)
    return np.asarray(amps)[order], np.asarray(torques)[order]


def fit_loading_curve(amplitude_rad: np.ndarray, torque_nm: np.ndarray) -> tuple[float, float, float] | None:
    """The elastoslide paper, eq. 24 through the loop tips by least squares: (phi0 1/(N*m), k, k0 N*m/rad).

    Needs at least three amplitude levels spanning a factor of 1.5; else None.
    """
    a, t = np.asarray(amplitude_rad), np.asarray(torque_nm)
    if a.size < 3 or a.max() < 1.5 * a.min():
        return None
    k_tot = t[0] / a[0]
    k0 = max((t[-1] - t[-2]) / max(a[-1] - a[-2], 1e-300), 1e-3 * k_tot)
    k0 = min(k0, 0.9 * k_tot)
    f_slip = max(t[-1] - k0 * a[-1], 1e-3 * t[-1])
    z0 = np.log([1.0 / f_slip, k_tot - k0, k0])

    def resid(z):
        phi0, k, kk0 = np.exp(z)
        return (loading_curve(a, phi0, k, kk0) - t) / t.max()

    r = least_squares(resid, z0, method="trf", bounds=(z0 - 12, z0 + 12))
    return tuple(map(float, np.exp(r.x))) if r.success else None  # type: ignore[return-value]


def rate_at_exponent(values: np.ndarray, names: list[str], p_new: int, rate_rad_per_s: float) -> np.ndarray:
    """``values`` moved to the odd exponent ``p_new``, v_r moved with it so that the slip-rate
    law (v / v_r)^(1/p) keeps its value at the typical rate ``rate_rad_per_s`` of the data."""
    iv, ip = names.index("v_r_rad_per_s"), names.index("p")
    out = np.array(values, float)
    out[iv] = rate_rad_per_s * (out[iv] / rate_rad_per_s) ** (p_new / int(out[ip]))
    out[ip] = p_new
    return out


def identify_elastoslide(s: Setup, segments: list[Segment], start: float, **_) -> Identification:
    """The elastoslide paper's route. Any angle history gives the same torque for (phi0, v_r) and
    (phi0 / a, v_r a^p), so phi0 is taken from the loop-tip loading curve (eq. 24, as the elastoslide paper
    does) and the identifiable combination is reported as the mean slip torque of the yield
    distribution when sliding at 1 rad/s, (1/phi0) (1 rad/s / v_r)^(1/p)."""
    fam: ElastoslideFamily = s.family  # type: ignore[assignment]
    x = s.x0.copy()
    extra: dict[str, Any] = {}
    amps, tips = loop_tips(segments)
    curve = fit_loading_curve(amps, tips)
    extra["loop_tips"] = {"amplitude_rad": amps.tolist(), "torque_nm": tips.tolist()}
    if curve is not None:
        for name, value in zip(("phi0_per_nm", "k_nm_per_rad", "k0_nm_per_rad"), curve):
            s.set_estimate(x, name, value)
        extra["loading_curve"] = dict(zip(("phi0_per_nm", "k_nm_per_rad", "k0_nm_per_rad"), curve))
    # v_r for the middle exponent by a grid search, every candidate in one call of the core
    p_list = sorted(int(p) for p in fam.options["p_candidates"])
    iv, ip = s.index("v_r_rad_per_s"), s.index("p")
    if not s.given[ip]:
        x[ip] = p_list[len(p_list) // 2]
    counter = Counter()
    if not s.given[iv]:
        cands = np.repeat(x[None, :], 11, axis=0)
        cands[:, iv] = np.geomspace(1e-4, 10.0, 11) * fam.scale.rate_rad_per_s
        cands = np.array([clip_to_bounds(fam.parameters, c) for c in cands])
        best, costs = batch_search(fam, segments, cands, counter)
        x = cands[best].copy()
        extra["v_r_search"] = {"p": int(x[ip]), "v_r_rad_per_s": cands[:, iv].tolist(),
                               "sum_squared_error_nm2": costs.tolist()}
    extra["search_evaluations"] = counter.evaluations
    # phi0 stays at the loading-curve value: the model is invariant under phi0 -> phi0 / a,
    # v_r -> v_r a^p (every slider's f* scales by a, and v_r (k e / f*)^p is unchanged), so
    # only v_r phi0^p is identifiable; the elastoslide paper fixes phi0 by the loading curve the same way
    continuous = ["k_nm_per_rad", "k0_nm_per_rad", "v_r_rad_per_s"] + fam.names[5:]
    fits = {int(x[ip]): s.fit(segments, x, continuous, f"joint at p = {int(x[ip])}")}
    if not s.given[ip]:
        # walk p over the odd candidates while the cost falls. Moving to p', v_r is moved so
        # that the slip-rate law (v / v_r)^(1/p) keeps its value at the data's rms rate.
        v_typ = ServoProblem(fam, segments).typical_rate_rad_per_s

        def try_p(frm: FitResult, p_new: int) -> FitResult:
            start_x = fam.move_choice(frm.values, ip, p_new, v_typ)
            return s.fit(segments, clip_to_bounds(fam.parameters, start_x), continuous, f"joint at p = {p_new}")

        fits = walk_choice(fits[int(x[ip])], lambda r: int(r.values[ip]), try_p, lambda r: r.metrics.rmse_nm, p_list)
    best = min(fits.values(), key=lambda r: r.metrics.rmse_nm)
    extra["p_walk"] = {int(p): r.metrics.nrmse for p, r in sorted(fits.items())}
    stages = [r for _, r in sorted(fits.items())]
    stages.remove(best)
    return result_of(s, segments, best.values.copy(), stages + [best], start, extra=extra)


FAMILY = ElastoslideFamily
strategy = identify_elastoslide


def __getattr__(name: str) -> object:
    """``walk_p``: deprecated, it is :func:`droptower.identify.engine.search.walk_choice`
    (removed in the next release)."""
    if name == "walk_p":
        import warnings

        warnings.warn("droptower.identify.families.elastoslide.walk_p is deprecated: use "
                      "droptower.identify.engine.search.walk_choice", DeprecationWarning, stacklevel=2)
        return walk_choice
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
