"""A wall-time budget for an identification, checked between calls of the core.

A fit cannot be interrupted inside a call of the core (a batched, compiled simulation), but it
makes hundreds of them: :func:`check` before each call raises :class:`BudgetExceeded` once the
budget set by :func:`time_budget` has run out, so a family that does not converge in its
budget stops within one core call of it (``compare_models`` lists it "not converged"). The
deadline is a context variable: budgets nest (the inner one never outlasts the outer one) and
code outside any budget runs unbounded.
"""
from __future__ import annotations

import contextvars
import math
import time
from contextlib import contextmanager
from typing import Iterator

#: The clock of every budget (s, monotonic): ``time.perf_counter``; a test injects its own.
clock = time.perf_counter


def now() -> float:
    """The budgets' clock now (s): :data:`clock` looked up at each call, so an injected one holds."""
    return clock()


#: (deadline on the budgets' clock, the budget in s) of the innermost budget
_DEADLINE: contextvars.ContextVar[tuple[float, float]] = contextvars.ContextVar("droptower_identify_deadline",
                                                                                default=(math.inf, math.inf))


class BudgetExceeded(RuntimeError):
    """The identification's wall-time budget ran out (not bad input: the fit took too long)."""

    def __init__(self, budget_s: float):
        super().__init__(f"did not converge within its time budget of {budget_s:g} s")
        self.budget_s = budget_s


@contextmanager
def time_budget(seconds: float | None) -> Iterator[None]:
    """Within the block, :func:`check` raises :class:`BudgetExceeded` after ``seconds`` of wall
    time (None or inf: no budget)."""
    if seconds is None or not math.isfinite(seconds):
        yield
        return
    if not seconds > 0:
        raise ValueError(f"a time budget must be positive, got {seconds!r}")
    outer = _DEADLINE.get()
    deadline = now() + float(seconds)
    token = _DEADLINE.set((deadline, float(seconds)) if deadline < outer[0] else outer)
    try:
        yield
    finally:
        _DEADLINE.reset(token)


def check() -> None:
    """Raise :class:`BudgetExceeded` when the current budget has run out."""
    deadline, seconds = _DEADLINE.get()
    if now() > deadline:
        raise BudgetExceeded(seconds)


def remaining_s() -> float:
    """Seconds left of the current budget (inf outside one)."""
    return _DEADLINE.get()[0] - now()
