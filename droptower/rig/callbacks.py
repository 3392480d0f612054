"""Exceptions raised in pymunk's collision callbacks, raised again after the step.

pymunk calls the scene's ``begin``, ``pre_solve`` and ``separate`` callbacks from C through
cffi. An exception that leaves such a callback, be it a defect or Ctrl-C's
``KeyboardInterrupt`` arriving while it runs, does not propagate: cffi hands it to
:func:`sys.unraisablehook` (which prints it), the callback counts as returned and the step goes
on. The contact is then not counted or its restitution not set, and the test's record is
silently wrong (a Ctrl-C landing there let a campaign run on to its end, with one test's record
spoilt). :func:`raising_callback_errors` keeps such an exception, per thread, and its
``check`` raises it where the step returns.
"""
from __future__ import annotations

import sys
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager

# in cffi's message for an exception that left a callback ("Exception ignored from cffi callback ...")
CFFI_CALLBACK = "cffi callback"

_lock = threading.Lock()
_watched: dict[int, list[BaseException]] = {}  # thread id -> exceptions its callbacks raised
_previous_hook: Callable | None = None


def _hook(unraisable) -> None:
    """Keep an exception from a cffi callback of a watched thread; pass anything else on."""
    caught = _watched.get(threading.get_ident())
    if caught is not None and CFFI_CALLBACK in (unraisable.err_msg or ""):
        exc = unraisable.exc_value if unraisable.exc_value is not None else unraisable.exc_type()
        caught.append(exc.with_traceback(unraisable.exc_traceback))
        return
    (_previous_hook or sys.__unraisablehook__)(unraisable)


@contextmanager
def raising_callback_errors() -> Iterator[Callable[[], None]]:
    """Within the block, an exception that leaves a cffi callback of this thread is kept rather
    than printed; the yielded ``check()`` raises the first one kept (call it after each
    ``space.step``), and leaving the block raises any left. The hook is installed while any
    thread is in such a block and the previous one is restored after the last."""
    global _previous_hook
    ident = threading.get_ident()
    with _lock:
        if not _watched:
            _previous_hook = sys.unraisablehook
            sys.unraisablehook = _hook
        _watched[ident] = caught = []

    def check() -> None:
        if caught:
            exc = caught[0]
            caught.clear()
            raise exc

    try:
        yield check
        check()
    finally:
        with _lock:
            del _watched[ident]
            if not _watched:
                sys.unraisablehook = _previous_hook
                _previous_hook = None
