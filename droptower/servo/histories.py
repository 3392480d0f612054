"""Imposed angle histories of the virtual servo-hydraulic bench (SI: s, rad).

Each function returns a :class:`History`: sample times ``time_s`` (sample n at n / fs),
the angle ``angle_rad`` and ``segments``, markers that say what each stretch of the history
is for. Every history starts at rest at angle 0 (the coupling's virgin state, see
:meth:`droptower.Coupling.simulate`) and moves smoothly: a servo cannot jump, and a jump in
the imposed angle or its rate would start transients that the run-in cycles must then wait
out. Oscillating segments hold whole cycles, so their evaluation windows close.

The test patterns are those of the source papers: sines with a preload offset, stepped
frequency and amplitude sweeps (Rapp et al. 2022, docs/theory.md#servo, the zero-dimensional model paper), two superposed sines
(the elastoslide paper, eq. 3), steps and slow ramps (the zero-dimensional model paper), and a band-limited random profile
(the zero-dimensional model paper's validation test).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from fractions import Fraction
from typing import Callable, Sequence

import numpy as np

from droptower.errors import DroptowerError
from droptower.limits import require_memory

#: Part of a cycle the oscillation runs on after the last evaluation cycle, so that the
#: smoothing filter and the interpolation see data beyond the evaluation window's end.
TAIL_CYCLES = 0.5

RUN_IN = "run-in"
EVALUATION = "evaluation"


@dataclass(frozen=True)
class Segment:
    """One stretch of a history, ``start_s`` <= t < ``stop_s``.

    label: ``offset ramp``, ``run-in``, ``evaluation``, ``tail``, ``rise``, ``hold``,
    ``ramp``, ``random``. For oscillating segments: ``frequency_hz`` is the base frequency
    (the segment holds whole base cycles), ``amplitude_rad`` the amplitude reached,
    ``offset_rad`` the mean angle; a dual-frequency segment lists its superposed
    ``components_hz`` and ``component_amplitudes_rad``.
    """

    label: str
    start_s: float
    stop_s: float
    frequency_hz: float = math.nan
    amplitude_rad: float = math.nan
    offset_rad: float = 0.0
    components_hz: tuple[float, ...] = ()
    component_amplitudes_rad: tuple[float, ...] = ()

    @property
    def duration_s(self) -> float:
        return self.stop_s - self.start_s

    @property
    def cycles(self) -> int:
        """Whole base cycles in the segment (0 for a non-oscillating segment)."""
        if not math.isfinite(self.frequency_hz):
            return 0
        return int(round(self.duration_s * self.frequency_hz))


@dataclass(frozen=True)
class History:
    """A sampled angle history with its segment markers (SI)."""

    time_s: np.ndarray
    angle_rad: np.ndarray
    segments: tuple[Segment, ...]
    sample_rate_hz: float

    @property
    def dt_s(self) -> float:
        return 1.0 / self.sample_rate_hz

    @property
    def evaluation_segments(self) -> list[Segment]:
        return [s for s in self.segments if s.label == EVALUATION]

    def indices(self, segment: Segment) -> slice:
        """Sample indices of the samples inside ``segment``."""
        start = int(math.ceil(segment.start_s * self.sample_rate_hz - 1e-9))
        stop = int(math.ceil(segment.stop_s * self.sample_rate_hz - 1e-9))
        return slice(max(start, 0), min(stop, self.time_s.size))


# --------------------------------------------------------------------------- building blocks
def _smoothstep(u: np.ndarray) -> np.ndarray:
    """Raised cosine from 0 (u <= 0) to 1 (u >= 1), with zero slope at both ends."""
    return 0.5 * (1.0 - np.cos(np.pi * np.clip(u, 0.0, 1.0)))


@dataclass
class _Program:
    """Continuous-time pieces laid end to end; rendered at a sample rate."""

    pieces: list[tuple[Segment, Callable[[np.ndarray], np.ndarray]]] = field(default_factory=list)
    t: float = 0.0

    def add(self, label: str, duration_s: float, fn: Callable[[np.ndarray], np.ndarray], **marks) -> None:
        """Append ``fn(local time)`` for ``duration_s`` seconds."""
        self.pieces.append((Segment(label, self.t, self.t + duration_s, **marks), fn))
        self.t += duration_s

    def render(self, sample_rate_hz: float) -> History:
        samples = self.t * sample_rate_hz + 1.0
        # time and angle, float64
        require_memory(16.0 * samples, f"a history of {self.t:.3g} s at {sample_rate_hz:g} Hz",
                       "use fewer or shorter segments (fewer cycles, higher frequencies) or a lower sample rate")
        n = int(math.floor(self.t * sample_rate_hz + 1e-9)) + 1
        time = np.arange(n) / sample_rate_hz
        angle = np.zeros(n)
        for seg, fn in self.pieces:
            lo = int(math.ceil(seg.start_s * sample_rate_hz - 1e-9))
            hi = int(math.ceil(seg.stop_s * sample_rate_hz - 1e-9))
            if seg is self.pieces[-1][0]:
                hi = n  # the last piece owns the closing sample
            angle[lo:hi] = fn(time[lo:hi] - seg.start_s)
        return History(time, angle, tuple(s for s, _ in self.pieces), float(sample_rate_hz))


def _check_rate(sample_rate_hz: float, frequencies_hz: Sequence[float]) -> None:
    if not (math.isfinite(sample_rate_hz) and sample_rate_hz > 0):
        raise DroptowerError(f"sample rate must be positive, got {sample_rate_hz} Hz")
    for f in frequencies_hz:
        if not (math.isfinite(f) and f > 0):
            raise DroptowerError(f"frequency must be positive, got {f} Hz")


def _check_cycles(run_in_cycles: int, cycles: int, ramp_cycles: int) -> None:
    if cycles < 1:
        raise DroptowerError(f"at least 1 evaluation cycle is needed, got {cycles}")
    if run_in_cycles < 1 or ramp_cycles < 1 or ramp_cycles > run_in_cycles:
        raise DroptowerError(f"need 1 <= ramp cycles ({ramp_cycles}) <= run-in cycles ({run_in_cycles})")


def _offset_ramp(prog: _Program, offset_rad: float, duration_s: float) -> None:
    prog.add("offset ramp", duration_s, lambda t: offset_rad * _smoothstep(t / duration_s), offset_rad=offset_rad)


def _oscillate(prog: _Program, wave: Callable[[np.ndarray], np.ndarray], frequency_hz: float, amp_from: float,
               amp_to: float, offset_rad: float, run_in_cycles: int, cycles: int, ramp_cycles: int,
               tail: bool, **marks) -> None:
    """Run-in cycles (amplitude blended from ``amp_from`` to ``amp_to`` over ``ramp_cycles``),
    evaluation cycles, optionally a tail. ``wave`` is the unit waveform of phase time t."""
    period = 1.0 / frequency_hz
    ramp_s = ramp_cycles * period

    def run_in(t):
        return offset_rad + (amp_from + (amp_to - amp_from) * _smoothstep(t / ramp_s)) * wave(t)

    marks = dict(frequency_hz=frequency_hz, amplitude_rad=amp_to, offset_rad=offset_rad, **marks)
    prog.add(RUN_IN, run_in_cycles * period, run_in, **marks)
    prog.add(EVALUATION, cycles * period, lambda t: offset_rad + amp_to * wave(t), **marks)
    if tail:
        prog.add("tail", TAIL_CYCLES * period, lambda t: offset_rad + amp_to * wave(t), **marks)


def _sine(frequency_hz: float) -> Callable[[np.ndarray], np.ndarray]:
    return lambda t: np.sin(2.0 * np.pi * frequency_hz * t)


# --------------------------------------------------------------------------- histories
def sine(frequency_hz: float, amplitude_rad: float, sample_rate_hz: float, *, offset_rad: float = 0.0,
         run_in_cycles: int = 5, cycles: int = 5, ramp_cycles: int = 2) -> History:
    """A sine about a preload offset, as a servo test runs it.

    Segments: ``offset ramp`` (raised cosine from 0 to ``offset_rad`` over ``ramp_cycles``
    periods; present, as a rest, even for offset 0 so that histories of one frequency have
    equal length), ``run-in`` (``run_in_cycles`` periods; the amplitude rises smoothly from 0
    over the first ``ramp_cycles``), ``evaluation`` (``cycles`` periods at full amplitude),
    ``tail`` (half a period). The angle is linear in ``offset_rad`` and ``amplitude_rad``.
    """
    _check_rate(sample_rate_hz, [frequency_hz])
    _check_cycles(run_in_cycles, cycles, ramp_cycles)
    prog = _Program()
    _offset_ramp(prog, offset_rad, ramp_cycles / frequency_hz)
    _oscillate(prog, _sine(frequency_hz), frequency_hz, 0.0, amplitude_rad, offset_rad, run_in_cycles, cycles,
               ramp_cycles, tail=True)
    return prog.render(sample_rate_hz)


def frequency_sweep(frequencies_hz: Sequence[float], amplitude_rad: float, sample_rate_hz: float, *,
                    offset_rad: float = 0.0, run_in_cycles: int = 5, cycles: int = 5,
                    ramp_cycles: int = 2) -> History:
    """A stepped frequency sweep at one amplitude: per frequency, run-in and evaluation cycles.

    Each step starts at a zero crossing (the angle is continuous; its rate steps, and the
    run-in cycles absorb that). One ``offset ramp`` at the start, one ``tail`` at the end.
    """
    _check_rate(sample_rate_hz, frequencies_hz)
    _check_cycles(run_in_cycles, cycles, ramp_cycles)
    if not len(frequencies_hz):
        raise DroptowerError("a frequency sweep needs at least one frequency")
    prog = _Program()
    _offset_ramp(prog, offset_rad, ramp_cycles / frequencies_hz[0])
    for i, f in enumerate(frequencies_hz):
        _oscillate(prog, _sine(f), f, 0.0 if i == 0 else amplitude_rad, amplitude_rad, offset_rad, run_in_cycles,
                   cycles, ramp_cycles, tail=i == len(frequencies_hz) - 1)
    return prog.render(sample_rate_hz)


def amplitude_sweep(amplitudes_rad: Sequence[float], frequency_hz: float, sample_rate_hz: float, *,
                    offset_rad: float = 0.0, run_in_cycles: int = 5, cycles: int = 5,
                    ramp_cycles: int = 2) -> History:
    """A stepped amplitude sweep at one frequency: the amplitude moves smoothly to each level
    during the first ``ramp_cycles`` of its run-in, then ``cycles`` are evaluated."""
    _check_rate(sample_rate_hz, [frequency_hz])
    _check_cycles(run_in_cycles, cycles, ramp_cycles)
    if not len(amplitudes_rad):
        raise DroptowerError("an amplitude sweep needs at least one amplitude")
    prog = _Program()
    _offset_ramp(prog, offset_rad, ramp_cycles / frequency_hz)
    previous = 0.0
    for i, a in enumerate(amplitudes_rad):
        _oscillate(prog, _sine(frequency_hz), frequency_hz, previous, a, offset_rad, run_in_cycles, cycles,
                   ramp_cycles, tail=i == len(amplitudes_rad) - 1)
        previous = a
    return prog.render(sample_rate_hz)


def common_frequency(frequencies_hz: Sequence[float], max_denominator: int = 1000) -> float:
    """The highest frequency of which all ``frequencies_hz`` are integer multiples (Hz).

    The elastoslide paper evaluates its 5 Hz + 7.5 Hz dual-frequency tests over the 2.5 Hz common period.
    Frequencies are read as fractions with denominators up to ``max_denominator``.
    """
    fracs = [Fraction(f).limit_denominator(max_denominator) for f in frequencies_hz]
    if any(abs(float(q) - f) > 1e-9 * f for f, q in zip(frequencies_hz, fracs)):
        raise DroptowerError(f"frequencies {list(frequencies_hz)} Hz have no common period "
                             f"(give them as fractions with denominators up to {max_denominator})")
    denominator = math.lcm(*[q.denominator for q in fracs])
    return math.gcd(*[int(q * denominator) for q in fracs]) / denominator


def dual_frequency(frequencies_hz: tuple[float, float], amplitudes_rad: tuple[float, float], sample_rate_hz: float,
                   *, offset_rad: float = 0.0, run_in_cycles: int = 5, cycles: int = 5,
                   ramp_cycles: int = 2) -> History:
    """Two superposed sines, x = A1 sin(2 pi f1 t) + A2 sin(2 pi f2 t) (the elastoslide paper, eq. 3).

    Cycles count periods of the common frequency (:func:`common_frequency`, 2.5 Hz for
    the elastoslide paper's 5 + 7.5 Hz), so the evaluation window holds whole cycles of both components.
    """
    _check_rate(sample_rate_hz, frequencies_hz)
    _check_cycles(run_in_cycles, cycles, ramp_cycles)
    if len(frequencies_hz) != 2 or len(amplitudes_rad) != 2:
        raise DroptowerError("a dual-frequency history needs two frequencies and two amplitudes")
    base = common_frequency(frequencies_hz)
    (f1, f2), (a1, a2) = frequencies_hz, amplitudes_rad

    peak = abs(a1) + abs(a2)
    if peak <= 0:
        raise DroptowerError("a dual-frequency history needs a nonzero amplitude")

    def wave(t):  # normalised to the bound of its peak, so the segments carry that as amplitude
        return (a1 * np.sin(2.0 * np.pi * f1 * t) + a2 * np.sin(2.0 * np.pi * f2 * t)) / peak

    prog = _Program()
    _offset_ramp(prog, offset_rad, ramp_cycles / base)
    _oscillate(prog, wave, base, 0.0, peak, offset_rad, run_in_cycles, cycles, ramp_cycles, tail=True,
               components_hz=(float(f1), float(f2)), component_amplitudes_rad=(float(a1), float(a2)))
    return prog.render(sample_rate_hz)


def steps(levels_rad: Sequence[float], sample_rate_hz: float, *, hold_s: float = 1.0,
          rise_s: float = 0.01) -> History:
    """Steps from level to level (the zero-dimensional model paper's step tests): each ``rise`` is a raised cosine of
    ``rise_s`` seconds (a servo's finite slew), each ``hold`` lasts ``hold_s`` seconds."""
    _check_rate(sample_rate_hz, [])
    if not (hold_s > 0 and rise_s > 0):
        raise DroptowerError("hold_s and rise_s must be positive")
    prog = _Program()
    previous = 0.0
    for level in levels_rad:
        a, b = previous, float(level)
        prog.add("rise", rise_s, lambda t, a=a, b=b: a + (b - a) * _smoothstep(t / rise_s), offset_rad=b)
        prog.add("hold", hold_s, lambda t, b=b: np.full_like(t, b), offset_rad=b)
        previous = b
    return prog.render(sample_rate_hz)


def ramps(peak_rad: float, rate_rad_per_s: float, sample_rate_hz: float, *, cycles: int = 1,
          offset_rad: float = 0.0) -> History:
    """Slow triangular load ramps at a constant rate (the zero-dimensional model paper's quasi-static ramps):
    per cycle offset -> offset + peak -> offset - peak -> offset, every leg a ``ramp``."""
    _check_rate(sample_rate_hz, [])
    if not (peak_rad > 0 and rate_rad_per_s > 0 and cycles >= 1):
        raise DroptowerError("peak, rate and cycles of a ramp history must be positive")
    prog = _Program()
    if offset_rad:
        _offset_ramp(prog, offset_rad, 2.0 * abs(offset_rad) / rate_rad_per_s)
    legs = [(0.0, peak_rad)] + [(peak_rad, -peak_rad), (-peak_rad, peak_rad)] * cycles
    legs[-1] = (-peak_rad, 0.0)
    for a, b in legs:
        dur = abs(b - a) / rate_rad_per_s
        prog.add("ramp", dur, lambda t, a=a, b=b, dur=dur: offset_rad + a + (b - a) * t / dur, offset_rad=offset_rad)
    return prog.render(sample_rate_hz)


def random_profile(rms_rad: float, band_hz: tuple[float, float], duration_s: float, sample_rate_hz: float, *,
                   seed: int = 0, offset_rad: float = 0.0, fade_s: float | None = None) -> History:
    """Band-limited random angle (the zero-dimensional model paper's random validation test), reproducible by ``seed``.

    White Gaussian noise from ``numpy.random.default_rng(seed)``, filtered zero-phase by a
    4th-order Butterworth band-pass ``band_hz`` = (low, high) (low = 0: low-pass), faded in
    and out over ``fade_s`` (default: one period of the band's lower edge, or 10 % of the
    duration for a low-pass) so that it starts from rest, then scaled to the RMS ``rms_rad``
    about ``offset_rad`` (reached by an ``offset ramp`` first when nonzero).
    """
    lo, hi = map(float, band_hz)
    _check_rate(sample_rate_hz, [hi])
    if not (0.0 <= lo < hi < 0.5 * sample_rate_hz):
        raise DroptowerError(f"band {band_hz} Hz must satisfy 0 <= low < high < half the sample rate "
                             f"({0.5 * sample_rate_hz:g} Hz)")
    if not (rms_rad > 0 and duration_s > 0):
        raise DroptowerError("rms and duration of a random profile must be positive")
    fade = fade_s if fade_s is not None else (1.0 / lo if lo > 0 else 0.1 * duration_s)
    if not 0 < 2 * fade < duration_s:
        raise DroptowerError(f"fade-in/out of {fade:g} s does not fit into {duration_s:g} s")
    from scipy import signal  # here, not at the top: every importer of the bench would pay ~1 s for it

    n = int(round(duration_s * sample_rate_hz))
    noise = np.random.default_rng(seed).standard_normal(n)
    if lo > 0:
        sos = signal.butter(4, [lo, hi], btype="bandpass", fs=sample_rate_hz, output="sos")
    else:
        sos = signal.butter(4, hi, btype="lowpass", fs=sample_rate_hz, output="sos")
    x = signal.sosfiltfilt(sos, noise)
    x *= _smoothstep(np.arange(n) / (fade * sample_rate_hz)) * _smoothstep((n - 1 - np.arange(n)) / (fade * sample_rate_hz))
    x *= rms_rad / np.sqrt(np.mean(x * x))

    t_x = np.arange(n) / sample_rate_hz
    prog = _Program()
    if offset_rad:
        _offset_ramp(prog, offset_rad, fade)
    prog.add("random", t_x[-1], lambda t: offset_rad + np.interp(t, t_x, x), offset_rad=offset_rad)
    return prog.render(sample_rate_hz)
