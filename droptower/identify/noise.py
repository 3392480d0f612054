"""The noise floor of identification data, estimated from the data alone (no model).

Servo records: the residual of a local quintic smoothing fit (Savitzky-Golay) of the measured
torque. A smoothing filter that is a projection onto local polynomials (centre weight h0)
passes white noise of variance s^2 into its residual with variance s^2 (1 - h0), so the
residual's spread over sqrt(1 - h0) estimates the noise; signals that vary slowly over the
window (a few ms at the bench's sample rates) leave no residual. The spread is the median
absolute deviation (times 1.4826, Gaussian-consistent), so the few samples where the signal
itself turns sharply (a slip, a turning point of a hysteresis) do not count as noise. The
residual's lag-1 correlation (over the samples within 4 sigma) gives the noise's effective
sample size (an AR(1) noise).

Drop-test logs: the angle sensor's standard deviation before the trigger (the lever at rest).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from droptower.identify.data import Segment

#: Samples of the smoothing window and the polynomial order of the local fit.
WINDOW = 11
ORDER = 5


@dataclass(frozen=True)
class NoiseFloor:
    """sigma: the noise's standard deviation (the data's unit); lag1: its lag-1 correlation
    (0 for white noise, clipped to [0, 0.99]); n_samples: compared samples; n_eff: the
    effective number of independent samples n (1 - lag1) / (1 + lag1)."""

    sigma: float
    lag1: float
    n_samples: int

    @property
    def n_eff(self) -> float:
        return max(self.n_samples * (1.0 - self.lag1) / (1.0 + self.lag1), 1.0)


def _centre_weight(window: int, order: int) -> float:
    from scipy.signal import savgol_filter

    impulse = np.zeros(window)
    impulse[window // 2] = 1.0
    return float(savgol_filter(impulse, window, order, mode="interp")[window // 2])


def servo_noise(segments: list[Segment]) -> NoiseFloor:
    """The torque's noise floor (N*m) over the compared runs of every segment."""
    # scipy.signal here, not at the top: the drop-test route imports this module and never smooths
    from scipy.signal import savgol_filter

    h0 = _centre_weight(WINDOW, ORDER)
    residuals = []
    n_all = 0
    for seg in segments:
        y = seg.torque_nm
        ok = np.isfinite(y)
        n_all += int(ok.sum())
        # contiguous compared runs long enough to smooth
        edges = np.flatnonzero(np.diff(np.concatenate([[0], ok.astype(int), [0]])))
        for a, b in zip(edges[::2], edges[1::2]):
            if b - a < 4 * WINDOW:
                continue
            r = y[a:b] - savgol_filter(y[a:b], WINDOW, ORDER)
            residuals.append(r[WINDOW:-WINDOW])  # the ends are fitted one-sided
    if not residuals:
        return NoiseFloor(float("nan"), 0.0, n_all)
    spread = 1.4826 * float(np.median(np.abs(np.concatenate(residuals))))
    num = sq = 0.0
    for r in residuals:
        r = np.where(np.abs(r) <= 4.0 * spread, r, 0.0)
        num += float(r[:-1] @ r[1:])
        sq += float(r @ r)
    # the filter's own correlation of a white residual is negative: a positive lag-1 is the noise's
    lag1 = float(np.clip(num / sq if sq > 0 else 0.0, 0.0, 0.99))
    return NoiseFloor(spread / np.sqrt(1.0 - h0), lag1, n_all)
