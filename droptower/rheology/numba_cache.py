"""Where numba may cache the compiled kernels, and compiling without a cache when nowhere can.

numba caches compiled functions beside their source (``__pycache__``), else under
``NUMBA_CACHE_DIR`` or the user's cache folder. A user with none of them writable (a
read-only install and no writable home) got "cannot cache function" at import. Then the
kernels cache into a private temporary folder, and where even that fails they are compiled
at every start (a few seconds more, the same code).
"""
from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from pathlib import Path


def _probe(x):  # decorated with cache=True to ask numba whether it finds a cache location here
    return x


def _numba_can_cache() -> None:
    from numba import njit

    njit(cache=True)(_probe)  # numba looks for a writable cache location when decorating, not when compiling


def cache_available(can_cache: Callable[[], None] = _numba_can_cache) -> bool:
    """True if compiled kernels beside this file can be cached (numba's own search, then a private
    temporary folder set as numba's cache folder); False: compile without caching."""
    from numba.core import config

    try:
        can_cache()
        return True
    except RuntimeError:  # "cannot cache function ...: no locator available"
        pass
    previous = config.CACHE_DIR
    private = Path(tempfile.gettempdir()) / f"droptower-numba-cache-{os.getuid() if hasattr(os, 'getuid') else 0}"
    try:
        private.mkdir(mode=0o700, exist_ok=True)
        config.CACHE_DIR = str(private)
        can_cache()
        return True
    except (OSError, RuntimeError):
        config.CACHE_DIR = previous
        return False


def prefer_fork_safe_threads() -> None:
    """Let numba's parallel regions use a fork-safe threading layer (TBB where installed, else its
    own work queue) unless the user chose one (``NUMBA_THREADING_LAYER``).

    Campaigns fork worker processes after the parent ran parallel regions (the preload of a
    batch); GNU OpenMP, numba's default where TBB is missing, is not fork-safe: a forked worker
    that enters a parallel region aborts.
    """
    from numba.core import config

    if "NUMBA_THREADING_LAYER" not in os.environ:
        config.THREADING_LAYER = "forksafe"


def parallel_twin(func: Callable) -> Callable:
    """A copy of ``func`` under the name ``<name>_parallel``, to be compiled with
    ``parallel=True`` beside a serial build of ``func``.

    numba's cache files are named after the function's qualified name and first line and do
    not tell a parallel build from a serial one of the same function (its cache key leaves the
    ``parallel`` flag out): whichever was compiled first was loaded for both, so the parallel build ran serially (or a
    serial caller ran the parallel one). The twin has its own name, hence its own cache entry.
    """
    import types

    twin = types.FunctionType(func.__code__, func.__globals__, f"{func.__name__}_parallel",
                              func.__defaults__, func.__closure__)
    twin.__qualname__ = f"{func.__qualname__}_parallel"
    twin.__doc__ = func.__doc__
    return twin
