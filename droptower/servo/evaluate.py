"""Lab-style evaluation of steady-state cycles of a torque-angle record (SI).

What a test lab does with a servo-hydraulic sine test (ISO 4664-1, DIN 740-2; docs/theory.md#servo, #damping-measures), on a record sampled at a uniform rate:

1. smooth angle and torque with a Savitzky-Golay filter one eighth of a cycle wide
   (docs/theory.md#servo); when that is fewer than :data:`MIN_WINDOW` samples the signals stay unsmoothed and
   the result says so (``smoothing_window_samples = 0``);
2. cut the evaluation cycles (the run-in cycles before them are discarded) and resample them
   by cubic-spline interpolation onto :data:`POINTS_PER_CYCLE` points per cycle, so that the
   window holds exactly whole cycles whatever the sample rate, peaks between samples are
   found, and the loop closes;
3. first-harmonic storage and loss stiffness from the Fourier coefficients over the whole
   cycles (the elastoslide paper, eq. 6): K* = K' + iK'' = (T_c - i T_s) / (phi_c - i phi_s), dynamic
   stiffness |K*|, loss angle arg K*, loss factor eta = K''/K';
4. damping work W_D, the loop area (closed integral of T dphi) per cycle, from the signals
   themselves (a polygon over the resampled loop, not through the Fourier coefficients);
   elastic work W_el = T_hat phi_hat / 2 with T_hat, phi_hat half peak-to-peak; relative
   damping psi = W_D / W_el (DIN 740-2 style). For a linear model W_D = pi K'' phi_hat^2
   and psi = 2 pi eta / sqrt(1 + eta^2), which is 2 pi eta to first order (docs/theory.md#damping-measures);
5. for comparison with the drop tower, clearly labelled, the drop-tower-equivalent damping
   ratio of docs/theory.md#extraction, #damping-measures (:func:`drop_tower_equivalent_damping_ratio`).

Smoothing is linear, zero-phase and the same for both signals, so it leaves K' and K''
unchanged; it scales the first harmonics by its gain at the test frequency (1 - 1e-4 for the
cubic one-eighth-cycle filter), so W_D by 1 - 2e-4. Smooth loops keep their psi. Loops with
hard corners (Coulomb sliders: ``prandtl``, ``masing``) get their corners rounded, which
lifts T_hat (by 5 % for a Prandtl element driven to 10 times its slip angle) and lowers psi
alike, as it would in the lab; ``smooth=False`` gives the model's own values. A dual-frequency
record is smoothed over one eighth of a cycle of its highest frequency.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from droptower.errors import DroptowerError, expects, finite_values
from droptower.sdof import drop_tower_equivalent_damping_ratio

#: Savitzky-Golay polynomial order; the filter needs a window of at least order + 2 samples.
SG_POLYORDER = 3
MIN_WINDOW = SG_POLYORDER + 2
#: Resampling density of the evaluation window (points per base cycle). The polygon loop
#: area then underestimates a smooth loop by (2 pi / 1024)^2 / 6 = 6e-6.
POINTS_PER_CYCLE = 1024
#: The fewest samples per cycle the evaluation accepts (a coarser record cannot resolve the
#: loop: one-eighth-cycle smoothing and the cubic interpolation both need more).
MIN_SAMPLES_PER_CYCLE = 20


def smoothing_window(sample_rate_hz: float, frequency_hz: float) -> int:
    """Savitzky-Golay window one eighth of a cycle wide (odd, samples); 0 when that is fewer
    than :data:`MIN_WINDOW` samples (then the signals are not smoothed)."""
    w = int(round(sample_rate_hz / (8.0 * frequency_hz)))
    w += 1 - w % 2
    return w if w >= MIN_WINDOW else 0


@dataclass(frozen=True)
class Harmonic:
    """First-harmonic result at one excitation frequency (the elastoslide paper, eq. 6)."""

    frequency_hz: float
    angle_amplitude_rad: float          # amplitude of the angle's Fourier component
    complex_stiffness_nm_per_rad: complex  # K' + i K''


@dataclass(frozen=True)
class CycleEvaluation:
    """Evaluation of the steady-state cycles of one test (SI).

    ``harmonics`` holds one entry per excitation frequency (two for a dual-frequency test);
    the scalar stiffness properties refer to the first. Loop quantities (work, peaks) are per
    base cycle. ``steady_state_deviation`` is the largest deviation of a single cycle's
    |K*| (relative) or W_D (relative to W_el) from the mean over the evaluated cycles: a
    large value says the run-in was too short. ``loop_angle_rad``/``loop_torque_nm``: the
    last evaluated cycle, resampled, for plots.
    """

    frequency_hz: float
    cycles: int
    harmonics: tuple[Harmonic, ...]
    angle_amplitude_rad: float
    torque_amplitude_nm: float
    mean_angle_rad: float
    mean_torque_nm: float
    damping_work_j: float
    steady_state_deviation: float
    smoothing_window_samples: int
    sample_rate_hz: float
    loop_angle_rad: np.ndarray = field(repr=False)
    loop_torque_nm: np.ndarray = field(repr=False)

    @property
    def complex_stiffness_nm_per_rad(self) -> complex:
        return self.harmonics[0].complex_stiffness_nm_per_rad

    @property
    def storage_stiffness_nm_per_rad(self) -> float:
        return self.complex_stiffness_nm_per_rad.real

    @property
    def loss_stiffness_nm_per_rad(self) -> float:
        return self.complex_stiffness_nm_per_rad.imag

    @property
    def dynamic_stiffness_nm_per_rad(self) -> float:
        return abs(self.complex_stiffness_nm_per_rad)

    @property
    def loss_angle_rad(self) -> float:
        return math.atan2(self.loss_stiffness_nm_per_rad, self.storage_stiffness_nm_per_rad)

    @property
    def loss_factor(self) -> float:
        k1 = self.storage_stiffness_nm_per_rad
        return self.loss_stiffness_nm_per_rad / k1 if k1 else math.nan

    @property
    def elastic_work_j(self) -> float:
        """W_el = T_hat phi_hat / 2 (DIN 740-2 style; half peak-to-peak values)."""
        return 0.5 * self.torque_amplitude_nm * self.angle_amplitude_rad

    @property
    def relative_damping_psi(self) -> float:
        return self.damping_work_j / self.elastic_work_j if self.elastic_work_j else math.nan

    def records(self) -> list[dict[str, float]]:
        """One flat record per harmonic: SI values, degree variants, units in every name."""
        out = []
        for h in self.harmonics:
            k = h.complex_stiffness_nm_per_rad
            eta = k.imag / k.real if k.real else math.nan
            out.append({
                "frequency_hz": h.frequency_hz,
                "harmonic_angle_amplitude_rad": h.angle_amplitude_rad,
                "harmonic_angle_amplitude_deg": math.degrees(h.angle_amplitude_rad),
                "storage_stiffness_nm_per_rad": k.real,
                "storage_stiffness_nm_per_deg": math.radians(k.real),
                "loss_stiffness_nm_per_rad": k.imag,
                "loss_stiffness_nm_per_deg": math.radians(k.imag),
                "dynamic_stiffness_nm_per_rad": abs(k),
                "dynamic_stiffness_nm_per_deg": math.radians(abs(k)),
                "loss_angle_rad": math.atan2(k.imag, k.real),
                "loss_angle_deg": math.degrees(math.atan2(k.imag, k.real)),
                "loss_factor": eta,
                "base_frequency_hz": self.frequency_hz,
                "angle_amplitude_rad": self.angle_amplitude_rad,
                "angle_amplitude_deg": math.degrees(self.angle_amplitude_rad),
                "torque_amplitude_nm": self.torque_amplitude_nm,
                "mean_angle_rad": self.mean_angle_rad,
                "mean_angle_deg": math.degrees(self.mean_angle_rad),
                "mean_torque_nm": self.mean_torque_nm,
                "damping_work_j": self.damping_work_j,
                "elastic_work_j": self.elastic_work_j,
                "relative_damping_psi": self.relative_damping_psi,
                "drop_tower_equivalent_damping_ratio": float(drop_tower_equivalent_damping_ratio(eta)),
                "evaluated_cycles": self.cycles,
                "steady_state_deviation": self.steady_state_deviation,
                "smoothing_window_samples": self.smoothing_window_samples,
                "sample_rate_hz": self.sample_rate_hz,
            })
        return out


def _sample_rate(time_s: np.ndarray) -> float:
    """The uniform sample rate of ``time_s`` (Hz); a non-uniform time axis is an error."""
    if time_s.ndim != 1 or time_s.size < 2:
        raise DroptowerError("the record needs a time axis of at least 2 samples")
    dt = np.diff(time_s)
    step = float(np.median(dt))
    if not step > 0 or np.max(np.abs(dt - step)) > 1e-6 * step + 1e-12:
        raise DroptowerError("the time axis is not uniformly sampled (needed by the smoothing filter)")
    return 1.0 / step


def evaluate_cycles(time_s: np.ndarray, angle_rad: np.ndarray, torque_nm: np.ndarray, frequency_hz: float,
                    start_s: float, cycles: int, *, components_hz: Sequence[float] | None = None,
                    smooth: bool = True) -> CycleEvaluation:
    """Evaluate ``cycles`` whole cycles of ``frequency_hz`` starting at ``start_s``.

    ``time_s``, ``angle_rad``, ``torque_nm``: one uniformly sampled record (s, rad, N*m).
    ``components_hz``: the excitation frequencies to report K* at (default: ``frequency_hz``);
    each must be an integer multiple of ``frequency_hz`` (the common frequency of a
    dual-frequency test). ``smooth``: apply the one-eighth-cycle Savitzky-Golay filter.
    """
    time_s, angle, torque = (finite_values(v, n) for v, n in ((time_s, "time_s"), (angle_rad, "angle_rad"),
                                                              (torque_nm, "torque_nm")))
    if not (angle.shape == torque.shape == time_s.shape):
        raise DroptowerError(f"time, angle and torque differ in length ({time_s.size}, {angle.size}, {torque.size})")
    if not (math.isfinite(frequency_hz) and frequency_hz > 0) or cycles < 1:
        raise DroptowerError(f"need a positive frequency and at least one cycle (got {frequency_hz} Hz, {cycles})")
    fs = _sample_rate(time_s)
    components = [frequency_hz] if components_hz is None else [float(f) for f in components_hz]
    orders = [f / frequency_hz for f in components]
    if any(abs(o - round(o)) > 1e-6 or round(o) < 1 for o in orders):
        raise DroptowerError(f"frequencies {components} Hz are not multiples of the base frequency {frequency_hz} Hz")
    f_max = max(components)
    if fs / f_max < MIN_SAMPLES_PER_CYCLE:
        raise DroptowerError(f"sample rate {fs:g} Hz is too coarse for {f_max:g} Hz: {fs / f_max:.1f} samples per "
                             f"cycle, at least {MIN_SAMPLES_PER_CYCLE} needed")

    stop_s = start_s + cycles / frequency_hz
    window = smoothing_window(fs, f_max) if smooth else 0
    margin = window // 2 + 4  # filter edge effects and spline end conditions stay outside the window
    i0 = int(math.floor((start_s - time_s[0]) * fs + 1e-9)) - margin
    i1 = int(math.ceil((stop_s - time_s[0]) * fs - 1e-9)) + margin + 1
    if i0 < 0 or i1 > time_s.size:
        raise DroptowerError(f"the record ({time_s[0]:g} to {time_s[-1]:g} s) does not cover the evaluation window "
                             f"{start_s:g} to {stop_s:g} s with a margin of {margin} samples")
    # imported here: every importer of the bench (the identification's drop-test route among them)
    # would pay ~1 s for scipy.signal and scipy.interpolate
    from scipy.interpolate import CubicSpline
    from scipy.signal import savgol_filter

    t, x, y = time_s[i0:i1], angle[i0:i1], torque[i0:i1]
    if window:
        x = savgol_filter(x, window, SG_POLYORDER)
        y = savgol_filter(y, window, SG_POLYORDER)

    # resample exactly `cycles` whole cycles, M points each, plus the closing point
    m = POINTS_PER_CYCLE
    tq = start_s + np.arange(cycles * m + 1) / (m * frequency_hz)
    xs = CubicSpline(t, x)(tq)
    ys = CubicSpline(t, y)(tq)
    x_per, y_per = xs[:-1], ys[:-1]

    # the elastoslide paper, eq. 6 via the DFT over whole cycles: X[k] = (N/2)(c_k - i s_k)
    fx, fy = np.fft.rfft(x_per), np.fft.rfft(y_per)
    n = x_per.size
    harmonics = []
    for f, o in zip(components, orders):
        b = int(round(o)) * cycles
        harmonics.append(Harmonic(f, 2.0 * abs(fx[b]) / n, complex(fy[b] / fx[b]) if fx[b] else complex(math.nan)))

    # loop area per cycle: trapezoidal closed integral of T dphi over each resampled cycle
    dx = np.diff(xs).reshape(cycles, m)
    ym = (0.5 * (ys[1:] + ys[:-1])).reshape(cycles, m)
    work = np.sum(ym * dx, axis=1)
    angle_amp = 0.5 * float(np.ptp(xs))
    torque_amp = 0.5 * float(np.ptp(ys))

    # steadiness: each cycle's own first harmonic and loop area against the mean
    b1 = int(round(orders[0]))
    per_k = np.fft.rfft(y_per.reshape(cycles, m), axis=1)[:, b1] / np.fft.rfft(x_per.reshape(cycles, m), axis=1)[:, b1]
    k_mean = harmonics[0].complex_stiffness_nm_per_rad
    w_el = 0.5 * torque_amp * angle_amp
    with np.errstate(invalid="ignore", divide="ignore"):
        dev = max(float(np.max(np.abs(per_k - k_mean))) / abs(k_mean) if abs(k_mean) else 0.0,
                  float(np.max(np.abs(work - work.mean()))) / w_el if w_el else 0.0)

    return CycleEvaluation(
        frequency_hz=float(frequency_hz), cycles=int(cycles), harmonics=tuple(harmonics),
        angle_amplitude_rad=angle_amp, torque_amplitude_nm=torque_amp,
        mean_angle_rad=float(np.real(fx[0])) / n, mean_torque_nm=float(np.real(fy[0])) / n,
        damping_work_j=float(work.mean()), steady_state_deviation=dev, smoothing_window_samples=window,
        sample_rate_hz=fs, loop_angle_rad=xs[-m - 1:], loop_torque_nm=ys[-m - 1:])


@expects(history="droptower.servo.histories.History")
def evaluate_history(history, torque_nm: np.ndarray, *, smooth: bool = True) -> list[CycleEvaluation]:
    """Evaluate every ``evaluation`` segment of a :class:`~droptower.servo.histories.History`
    (one per step of a sweep) against the torque the coupling answered with."""
    out = []
    for seg in history.evaluation_segments:
        out.append(evaluate_cycles(history.time_s, history.angle_rad, torque_nm, seg.frequency_hz, seg.start_s,
                                   seg.cycles, components_hz=seg.components_hz or None, smooth=smooth))
    return out
