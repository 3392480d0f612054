"""Where numba may cache the compiled kernels, and compiling without a cache when nowhere can.

numba caches compiled functions beside their source (``__pycache__``), else under
``NUMBA_CACHE_DIR`` or the user's cache folder. A user with none of them writable (a
read-only install and no writable home) got "cannot cache function" at import. Then the
kernels cache into a private temporary folder, and where even that fails they are compiled
at every start (a few seconds more, the same code).
"""
from __future__ import annotations

import functools
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

    The package's own kernels run no parallel region (large batches run on Python threads,
    :mod:`droptower.rheology.threads`), but numba launches its threading layer where a kernel built
    with ``parallel=True`` (:func:`row_loop_options`) is loaded from the cache, and where a campaign
    worker sets its thread count; user code may run parallel regions before forking. GNU OpenMP,
    numba's default where TBB is missing, is not fork-safe: a forked worker that enters a parallel
    region aborts.
    """
    from numba.core import config

    if "NUMBA_THREADING_LAYER" not in os.environ:
        config.THREADING_LAYER = "forksafe"


def row_loop_options(path: str) -> dict:
    """The jit options of a batch kernel whose rows run in a plain ``range`` loop (the rows are
    spread over threads by :mod:`droptower.rheology.threads`, not by numba): ``parallel=True``.

    numba's parallel pipeline finds no loop to parallelise there (no ``prange``: no parallel
    region, no second build), but its passes simplify the typed IR (copy propagation, dead code
    removal) before lowering: the kernels ran ~23 % faster per row than from the default pipeline
    (measured single-threaded, bit-identical results) for ~0.7 s more compilation each. numba's
    warning that nothing was parallelised is turned off while it compiles the functions of
    ``path`` (a module's ``__file__``), whatever warning filters the caller set.
    """
    _quiet_files().add(os.path.abspath(path))
    return {"parallel": True}


@functools.cache
def _quiet_files() -> set[str]:
    """The files whose compilations run without numba's performance warnings (a listener of numba's
    compile events, registered once; compilations hold numba's global compiler lock, one at a time)."""
    from numba.core import config
    from numba.core import event as numba_event

    files: set[str] = set()

    class Quiet(numba_event.Listener):
        depth, previous = 0, None

        def on_start(self, event: numba_event.Event) -> None:
            dispatcher = event.data.get("dispatcher")
            code = getattr(getattr(dispatcher, "py_func", None), "__code__", None)
            if self.depth or (code is not None and os.path.abspath(code.co_filename) in files):
                if not self.depth:
                    self.previous = config.DISABLE_PERFORMANCE_WARNINGS
                    config.DISABLE_PERFORMANCE_WARNINGS = 1
                self.depth += 1

        def on_end(self, event: numba_event.Event) -> None:
            if self.depth:
                self.depth -= 1
                if not self.depth:
                    config.DISABLE_PERFORMANCE_WARNINGS = self.previous

    numba_event.register("numba:compile", Quiet())
    return files


#: how long a process waits for another one's compilation of the same kernel before compiling it
#: itself (a process that dies releases its lock at once; this bounds a hung one)
COMPILE_WAIT_S = 900.0


def compile_once_across_processes(namespace: dict) -> None:
    """Give every cached numba dispatcher in ``namespace`` (a module's ``globals()``) a cache that
    lets one process at a time compile it: a process that finds no cached build waits while
    another process compiles the same function, then loads that build from the cache.

    numba writes its cache only after compiling, so processes started together (the test suite's
    workers, a campaign's) that reach a kernel no cache holds yet each compiled it in full,
    ~10 s of CPU per large kernel. The lock is an advisory lock on a file beside the cache index
    (``fcntl.flock``: released when its holder exits); where there is no ``fcntl`` (Windows) or
    no writable cache, nothing changes. The compiled code is numba's, unchanged.
    """
    try:
        import fcntl  # noqa: F401  (POSIX only)
    except ImportError:
        return
    from numba.core.caching import FunctionCache
    from numba.core.registry import CPUDispatcher

    for value in namespace.values():
        if isinstance(value, CPUDispatcher) and type(getattr(value, "_cache", None)) is FunctionCache:
            value._cache = _compile_once_cache_class()(value.py_func)


@functools.cache
def _compile_once_cache_class() -> type:
    """The cache class (it subclasses numba's, so it is built when first used: importing this
    module imports no numba)."""
    import fcntl
    import time

    from numba.core import event as numba_event
    from numba.core.caching import FunctionCache

    class CompileOnceCache(FunctionCache):
        """numba's per-function cache; a miss takes the function's compile lock (until the build is
        saved) and looks again once it has it."""

        _lock_file = None

        def load_overload(self, sig, target_context):
            data = super().load_overload(sig, target_context)
            if data is not None or not self._enabled:
                return data
            self._release()  # a compilation of this process that failed before saving
            if not self._acquire():
                return None
            data = super().load_overload(sig, target_context)  # saved by the process we waited for
            if data is not None:
                self._release()
            return data

        def save_overload(self, sig, data):
            try:
                super().save_overload(sig, data)
            finally:
                self._release()

        def _acquire(self) -> bool:
            try:
                self._impl.locator.ensure_cache_path()
                handle = open(os.path.join(self.cache_path, self._impl.filename_base + ".lock"), "a")
            except (OSError, AttributeError):  # AttributeError: a numba whose cache is built otherwise
                return False  # compile as numba does by itself
            deadline = time.monotonic() + COMPILE_WAIT_S
            while True:
                try:
                    fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
                    self._lock_file = handle
                    return True
                except OSError:
                    if time.monotonic() > deadline:
                        handle.close()
                        return False
                    time.sleep(0.05)

        def _release(self) -> None:
            if self._lock_file is not None:
                self._lock_file.close()  # closing the file releases its flock
                self._lock_file = None

    class ReleaseOnFailure(numba_event.Listener):
        """A compilation that raises (a signature that does not type) saves nothing: release its lock
        there, or another process needing the function would wait for it."""

        def on_start(self, event: numba_event.Event) -> None:
            pass

        def on_end(self, event: numba_event.Event) -> None:
            dispatcher = event.data.get("dispatcher")
            cache = getattr(dispatcher, "_cache", None)
            # failed: no build for the signature (numba's own Event.is_failed reads the wrong way round)
            if isinstance(cache, CompileOnceCache) and tuple(event.data.get("args", ())) not in dispatcher.overloads:
                cache._release()

    numba_event.register("numba:compile", ReleaseOnFailure())
    return CompileOnceCache

