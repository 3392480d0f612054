"""Limits on the size of a request, checked before anything is allocated or run.

A typo such as ``duration_s=1e9`` or ``repeats = 1e7`` must not exhaust the memory or run for
days: every command estimates the memory (and, where it matters, the number of time steps) of
what it was asked, and refuses on one line that names the limit and how to split the work.

- memory of one request: :data:`MEMORY_LIMIT_BYTES` (2 GiB; the environment variable
  ``DROPTOWER_MEMORY_LIMIT_GB`` raises or lowers it);
- coupling time steps of one simulation call (all instances together): :data:`STEP_LIMIT`
  (1e9, about an hour on one core at 2-4 us per instance step);
- elements of one coupling file: :data:`MAX_ELEMENTS`; discrete elements of one element
  (elastoslide, masing ``n``): :data:`MAX_ELEMENT_N`; state variables of one coupling
  instance: :data:`MAX_COUPLING_STATE`;
- tests of one campaign: :data:`MAX_CAMPAIGN_TESTS`; test conditions of one plan
  (groups x heights x preloads): :data:`MAX_PLAN_CONDITIONS`;
- configuration files: :data:`MAX_CONFIG_BYTES` and :data:`MAX_CONFIG_DEPTH` (nesting).
"""
from __future__ import annotations

import math
import os
from typing import Any

from droptower.errors import DroptowerError

GIB = 2**30
MAX_ELEMENTS = 1000
MAX_ELEMENT_N = 10_000
MAX_COUPLING_STATE = 100_000
MAX_CAMPAIGN_TESTS = 100_000
MAX_PLAN_CONDITIONS = 5_000
STEP_LIMIT = 1e9
MAX_CONFIG_BYTES = 16 * 2**20
MAX_CONFIG_DEPTH = 32


def memory_limit_bytes() -> float:
    """The memory one request may use (bytes): ``DROPTOWER_MEMORY_LIMIT_GB`` GiB, default 2."""
    text = os.environ.get("DROPTOWER_MEMORY_LIMIT_GB", "")
    try:
        value = float(text) if text else 2.0
    except ValueError:
        raise DroptowerError(f"must be a number of GiB, got {text!r}", where="DROPTOWER_MEMORY_LIMIT_GB") from None
    if not value > 0:
        raise DroptowerError(f"must be positive, got {text!r}", where="DROPTOWER_MEMORY_LIMIT_GB")
    return value * GIB


def format_bytes(n: float) -> str:
    """``n`` bytes in binary units: ``"279 TiB"``, ``"1.5 GiB"``."""
    if not math.isfinite(n):
        return "an unbounded amount"
    for unit in ("B", "KiB", "MiB", "GiB", "TiB", "PiB"):
        if abs(n) < 1024 or unit == "PiB":
            return f"{n:.3g} {unit}"
        n /= 1024
    return f"{n:.3g} PiB"  # pragma: no cover


def require_memory(nbytes: float, what: str, split: str, **where: Any) -> None:
    """Refuse a request whose estimated memory ``nbytes`` exceeds the limit.

    what: what needs the memory (``"the record of 1 drop test of 1e+09 s"``); split: how to
    make it smaller (``"shorten `duration_s` to at most 870 s"``); ``where``/``file`` go to the
    :class:`DroptowerError`."""
    limit = memory_limit_bytes()
    if not nbytes <= limit:  # also refuses NaN
        amount = ("about " if math.isfinite(nbytes) else "") + format_bytes(nbytes)
        raise DroptowerError(f"{what} needs {amount} of memory, more than the limit of {format_bytes(limit)} "
                             f"(DROPTOWER_MEMORY_LIMIT_GB): {split}", **where)


def require_steps(steps: float, what: str, split: str, **where: Any) -> None:
    """Refuse a simulation of more than :data:`STEP_LIMIT` instance time steps (hours of run time)."""
    if not steps <= STEP_LIMIT:
        raise DroptowerError(f"{what} takes {steps:.3g} coupling time steps, more than the limit of "
                             f"{STEP_LIMIT:.0e} (about an hour): {split}", **where)


def nesting_depth(value: Any) -> int:
    """Levels of nested lists and dicts in ``value`` (a scalar: 0), counted without recursion."""
    depth, level = 0, [value]
    while level := [node for node in level if isinstance(node, (list, dict))]:
        depth += 1
        level = [child for node in level for child in (node.values() if isinstance(node, dict) else node)]
    return depth
