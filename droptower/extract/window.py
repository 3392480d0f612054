"""The fit window after the impact: ``first-cycle`` (Rapp et al. 2022: the first complete cycle),
``N-cycles`` (e.g. ``2-cycles``) or a length in seconds (e.g. ``0.05``).

A window shorter than three quarters of a period is refused: the damping cannot be deduced
from less (Rapp et al. 2022, section "Theory of Impact Investigation").
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass

from droptower.errors import DroptowerError

MIN_PERIODS = 0.75

_CYCLES = re.compile(r"^\s*(\d+(?:\.\d*)?)\s*-?\s*cycles?\s*$", re.IGNORECASE)


@dataclass(frozen=True)
class Window:
    """A window length in oscillation periods (``cycles``) or in seconds (``seconds``)."""

    cycles: float | None = 1.0
    seconds: float | None = None

    def __post_init__(self):
        for name in ("cycles", "seconds"):
            value = getattr(self, name)
            if value is not None and not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise DroptowerError(f"window {name}: must be a finite number > 0, got {value!r}")

    @classmethod
    def parse(cls, text: "str | Window") -> "Window":
        """``first-cycle`` | ``N-cycles`` | ``SECONDS`` -> Window; anything else is a DroptowerError."""
        if isinstance(text, Window):
            return text
        spec = str(text).strip().lower()
        if spec in ("first-cycle", "first cycle", "1-cycle"):
            return cls(cycles=1.0)
        match = _CYCLES.match(spec)
        try:
            window = cls(cycles=float(match.group(1))) if match else cls(cycles=None, seconds=float(spec))
        except ValueError:
            raise DroptowerError(f"window {text!r}: expected first-cycle, N-cycles (e.g. 2-cycles) or a length "
                                 "in seconds (e.g. 0.05)") from None
        except DroptowerError:
            raise DroptowerError(f"window {text!r}: must be a finite number > 0") from None
        return window

    def length_s(self, period_s: float) -> float:
        """Window length in s for an oscillation period of ``period_s``; refused below 3/4 period."""
        length = self.cycles * period_s if self.cycles is not None else self.seconds
        if length < MIN_PERIODS * period_s:
            size = f"{self} ({length:.4g} s)" if self.cycles is not None else str(self)
            raise DroptowerError(f"window {size} is shorter than 3/4 of the oscillation period ({period_s:.4g} s)")
        return length

    def __str__(self) -> str:
        if self.cycles is None:
            return f"{self.seconds:g} s"
        return "first-cycle" if self.cycles == 1.0 else f"{self.cycles:g}-cycles"
