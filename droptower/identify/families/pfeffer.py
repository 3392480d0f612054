"""Scheiblegger et al.'s (2013) linear Pfeffer bushing model (docs/theory.md#pfeffer): family and strategy.

The analytic route (k1 = static stiffness, alpha = DH - 1, gamma from the loss-peak
frequency, beta until the loss angle at the layout frequency matches), then least squares.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.optimize import brentq

from droptower.errors import DroptowerError
from droptower.identify.cycles import evaluate_block
from droptower.identify.data import Segment
from droptower.identify.families.base import Family, stiffness_parameter
from droptower.identify.families.stages import Setup, result_of, split_by_speed, static_stiffness, steady_blocks
from droptower.identify.fit import FitVariable, clip_to_bounds, simulate
from droptower.identify.result import Identification, metrics
from droptower.rheology.elements import Pfeffer

class PfefferFamily(Family):
    """Scheiblegger et al.'s (2013) linear Pfeffer model: k1 || c1 in series with (k2 || c2); alpha = k2/k1,
    beta = c2/c1, gamma = c1/k1 (docs/theory.md#pfeffer)."""

    kind = "pfeffer"
    title = "linear Pfeffer bushing model (k1, alpha, beta, gamma)"
    source = "Scheiblegger et al. 2013 (Pfeffer bushing model, linearised), docs/theory.md#pfeffer"
    OPTIONS = {"layout_frequency_hz": 0.0, "peak_frequency_hz": 0.0}

    def _parameters(self):
        return [stiffness_parameter("k1_nm_per_rad", self.scale), FitVariable("alpha", 1e-4, 1e3),
                FitVariable("beta", 0.0, 1e3, log=False), FitVariable("gamma_s", 1e-7, 1e3)]

    def guess(self):
        s = self.scale
        return np.array([0.5 * s.stiffness_nm_per_rad, 1.0, 0.01, 1.0 / (2 * np.pi * max(s.frequency_hz, 1e-3))])

    def elements(self, v):
        k1, alpha, beta, gamma = v
        return [{"kind": "pfeffer", "k1": k1, "alpha": alpha, "beta": beta, "gamma": gamma}]

    def derived(self, v):
        k1, alpha, beta, gamma = v
        return {"k2_nm_per_rad": alpha * k1, "c1_nms_per_rad": gamma * k1, "c2_nms_per_rad": beta * gamma * k1}


def pfeffer_complex_stiffness(v: np.ndarray, omega: np.ndarray | float) -> np.ndarray:
    """K*(Omega) of the linear Pfeffer model with parameters (k1, alpha, beta, gamma)."""
    k1, alpha, beta, gamma = v
    return Pfeffer(kind="pfeffer", k1=k1, alpha=alpha, beta=beta, gamma=gamma).complex_stiffness(np.asarray(omega))


def pfeffer_analytic(k_stat: float, k_dyn: float, loss_angle_rad: float, layout_frequency_hz: float,
                     peak_frequency_hz: float) -> dict[str, Any]:
    """Scheiblegger et al.'s (2013) analytic identification of the linear Pfeffer model (docs/theory.md#pfeffer).

    k1 = k_stat; k2 = k_stat (DH - 1) with DH = k_dyn / k_stat, so alpha = DH - 1; gamma puts
    the loss-angle peak of the beta = 0 model (k1 || Maxwell(k2, c1): tan delta peaks at
    Omega tau = 1/sqrt(1 + alpha), tau = gamma / alpha) at ``peak_frequency_hz``; beta is
    raised from 0 until the loss angle at the layout frequency equals ``loss_angle_rad``.
    Returns the parameters and notes on what could not be met.
    """
    notes = []
    dh = k_dyn / k_stat
    alpha = dh - 1.0
    if alpha <= 0:
        notes.append(f"dynamic hardening {dh:.3g} <= 1: alpha set to 1e-3")
        alpha = 1e-3
    gamma = alpha / (2 * np.pi * peak_frequency_hz * np.sqrt(1.0 + alpha))
    w = 2 * np.pi * layout_frequency_hz

    def miss(beta: float) -> float:
        return float(np.angle(pfeffer_complex_stiffness(np.array([k_stat, alpha, beta, gamma]), w))) - loss_angle_rad

    beta_max = 1e3
    if miss(0.0) >= 0:
        beta = 0.0
        notes.append("the loss angle at the layout frequency is reached without c2 (beta = 0)")
    elif miss(beta_max) < 0:
        beta = beta_max
        notes.append(f"the loss angle at the layout frequency is not reached up to beta = {beta_max:g}")
    else:
        beta = float(brentq(miss, 0.0, beta_max, xtol=1e-12, rtol=1e-10))
    v = np.array([k_stat, alpha, beta, gamma])
    k = complex(pfeffer_complex_stiffness(v, w))
    return {"k1_nm_per_rad": k_stat, "alpha": alpha, "beta": beta, "gamma_s": gamma,
            "dynamic_hardening": dh, "layout_frequency_hz": layout_frequency_hz,
            "peak_frequency_hz": peak_frequency_hz,
            "model_dynamic_stiffness_nm_per_rad": abs(k), "model_loss_angle_deg": math.degrees(np.angle(k)),
            "measured_dynamic_stiffness_nm_per_rad": k_dyn, "measured_loss_angle_deg": math.degrees(loss_angle_rad),
            "notes": notes}


def identify_pfeffer(s: Setup, segments: list[Segment], start: float, **_) -> Identification:
    fam: PfefferFamily = s.family  # type: ignore[assignment]
    x = s.x0.copy()
    extra: dict[str, Any] = {}
    evals = [(sb, evaluate_block(segments[sb.segment].measured_angle, segments[sb.segment].measured_torque,
                                 segments[sb.segment].dt_s, sb.block)) for sb in steady_blocks(segments)]
    evals = [(sb, ev) for sb, ev in evals if ev is not None]
    k_stat = static_stiffness(segments)
    if k_stat is None:
        slow, _ = split_by_speed(segments)
        if slow:  # regression slope of the quasi-static records
            xs = np.concatenate([g.measured_angle for g in slow])
            ys = np.concatenate([g.measured_torque for g in slow])
            ok = np.isfinite(ys)
            k_stat = float(xs[ok] @ ys[ok] / (xs[ok] @ xs[ok]))
        elif evals:  # the storage stiffness at the lowest frequency measured
            k_stat = min(evals, key=lambda e: e[1].frequency_hz)[1].storage_stiffness_nm_per_rad
    if evals and k_stat and k_stat > 0:
        freqs = np.array([ev.frequency_hz for _, ev in evals])
        # default: the measured block frequency nearest the median (the median of an even
        # number of block frequencies lies between two blocks)
        f_layout = float(fam.options["layout_frequency_hz"]) or float(
            freqs[np.argmin(np.abs(np.log(freqs / np.median(freqs))))])
        near = np.abs(np.log(freqs / f_layout)) <= np.log(1.1)
        if not near.any():
            raise DroptowerError(f"no steady sine block near the layout frequency {f_layout:g} Hz "
                                 f"(blocks at {', '.join(f'{f:.3g}' for f in sorted(set(freqs.round(3))))} Hz)")
        k_star = np.mean([ev.complex_stiffness_nm_per_rad for (_, ev), n in zip(evals, near) if n])
        f_peak = float(fam.options["peak_frequency_hz"]) or f_layout / 5.0
        analytic = pfeffer_analytic(k_stat, abs(k_star), float(np.angle(k_star)), f_layout, f_peak)
        extra["analytic"] = analytic
        for name in fam.names:
            s.set_estimate(x, name, analytic[name])
        extra["analytic_nrmse"] = metrics(segments, simulate(fam, clip_to_bounds(fam.parameters, x)[None], segments)[0]).nrmse
    r = s.fit(segments, x, None, "least squares")
    return result_of(s, segments, r.values.copy(), [r], start, extra=extra)


FAMILY = PfefferFamily
strategy = identify_pfeffer
