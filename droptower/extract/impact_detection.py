"""Impact detection: pre-trigger baseline, impact onset, end of contact, second impact.

The impact is the largest excursion of the force channel (or, without one, of the angle).
Its onset is where the signal leaves the pre-trigger band: the threshold is the larger of
``NOISE_FACTOR`` standard deviations of the pre-trigger noise and ``PEAK_FRACTION`` of the
peak. A second impact is a later excursion of the force beyond the same threshold after the
force stayed back in the band for at least ``MIN_GAP_S`` (Rapp et al. 2022: the impact lasts ~0.3 ms;
a second contact comes back milliseconds later, docs/theory.md#impact, #decay).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from droptower.errors import DroptowerError

NOISE_FACTOR = 6.0      # threshold in pre-trigger standard deviations
PEAK_FRACTION = 0.05    # threshold as a fraction of the impact's peak
IMPACT_SNR = 20.0       # an impact must exceed the pre-trigger noise by this factor
MIN_GAP_S = 1e-3        # force back in the band this long before another pulse counts as a second impact
MIN_PRETRIGGER = 8      # samples needed before the impact to estimate the baseline
GUARD = 2               # samples left out between the baseline and the onset


@dataclass(frozen=True)
class Impact:
    """Where the impact is in a record (sample indices into the common time base).

    onset: first sample beyond the threshold; contact_end: first sample after the pulse back in
    the band (equal to onset when detected from the angle); baseline_end: the pre-trigger is
    ``[0, baseline_end)``; second_onset: first sample of a second impact, or None; impulse_ns:
    ∫ F dt over the pulse in N·s (NaN without a force channel); source: the channel used.
    """

    onset: int
    contact_end: int
    baseline_end: int
    second_onset: int | None
    impulse_ns: float
    source: str


@dataclass(frozen=True)
class _Pulse:
    onset: int
    peak: int
    sign: float
    baseline: float
    above: np.ndarray


def _robust_std(x: np.ndarray) -> float:
    return 1.4826 * float(np.median(np.abs(x - np.median(x))))


def _pulse(x: np.ndarray, name: str) -> _Pulse:
    """The largest excursion of ``x`` and where it leaves the pre-trigger band."""
    centre = float(np.median(x))
    peak = int(np.argmax(np.abs(x - centre)))
    sign = 1.0 if x[peak] >= centre else -1.0
    # the pre-trigger lies before the excursion reaches half its peak; its first half is
    # surely quiet even if the rise is as long as the pre-trigger itself
    half = int(np.argmax(sign * (x - centre) > 0.5 * abs(x[peak] - centre)))
    pre = x[: half // 2]
    if pre.size < MIN_PRETRIGGER:
        raise DroptowerError(f"no impact found after a pre-trigger on channel '{name}': its largest excursion comes "
                             f"{half} sample(s) after the start of the record, at least {2 * MIN_PRETRIGGER} "
                             "are needed before the impact for the baseline")
    baseline, noise = float(np.median(pre)), _robust_std(pre)
    height = abs(x[peak] - baseline)
    if height <= IMPACT_SNR * noise or height == 0.0:
        raise DroptowerError(f"no impact found on channel '{name}': its largest excursion ({height:.3g}) is within "
                             f"{IMPACT_SNR:g}x the pre-trigger noise ({noise:.3g})")
    threshold = max(NOISE_FACTOR * noise, PEAK_FRACTION * height)
    above = sign * (x - baseline) > threshold
    quiet = np.flatnonzero(~above[:peak])
    onset = int(quiet[-1]) + 1 if quiet.size else 0
    if onset - GUARD < MIN_PRETRIGGER:
        raise DroptowerError(f"no impact found after a pre-trigger on channel '{name}': the impact starts at sample "
                             f"{onset}, at least {MIN_PRETRIGGER + GUARD} samples are needed before it for the baseline")
    return _Pulse(onset, peak, sign, baseline, above)


def find_impact(time_s: np.ndarray, angle_rad: np.ndarray, impact_force_n: np.ndarray | None) -> Impact:
    """Locate the impact from the force channel, or from the angle if there is none."""
    if impact_force_n is None:
        p = _pulse(angle_rad, "angle")
        return Impact(p.onset, p.onset, p.onset - GUARD, None, float("nan"), "angle")
    p = _pulse(impact_force_n, "impact_force")
    back = np.flatnonzero(~p.above[p.peak:])
    if not back.size:
        raise DroptowerError("the impact force never returns to its pre-trigger baseline after the impact",
                             where="channel 'impact_force'")
    contact_end = p.peak + int(back[0])
    pulse = slice(p.onset - 1, contact_end + 1)
    impulse = float(np.trapezoid(p.sign * (impact_force_n[pulse] - p.baseline), time_s[pulse]))
    later = np.flatnonzero(p.above[contact_end:]) + contact_end
    later = later[time_s[later] - time_s[contact_end] >= MIN_GAP_S]
    second = int(later[0]) if later.size else None
    return Impact(p.onset, contact_end, p.onset - GUARD, second, impulse, "impact_force")
