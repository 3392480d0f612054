"""Where numba caches the compiled kernels, keyed on the sources they are built from.

A kernel module's kernels are cached in one folder of the user's cache
(``platformdirs.user_cache_dir("droptower")/numba``, or ``NUMBA_CACHE_DIR`` where set) named by a
hash of the contents of every file of the package the module's code reaches
(:func:`kernel_sources`): the rig's kernels are built around the core's element steps and read
the generated slot constants of ``rheology/kernels.py``, which numba's own cache, keyed on the
kernel's own file, does not see (an edited ``kernels.py`` left ``rig/lever_decay.py``'s cached kernel
stale). The same sources compiled once serve every copy of them: a checkout and its installed
copy, a reinstall, an FMU's host process. Where that folder is not writable numba's own places
are used (beside the source in ``__pycache__``, then the user's numba cache).

A user with none of them writable (a read-only install and no writable home) got "cannot cache
function" at import. Then the kernels cache into a private temporary folder, and where even
that fails they are compiled at every start (a few seconds more, the same code).
"""
from __future__ import annotations

import functools
import hashlib
import os
import sys
import tempfile
import types
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
#: Cache folders of one kernel module kept side by side (the most recently changed; older ones
#: are removed when a new one is made): environments on a few different versions each find
#: their build, without the user's cache growing with every edit of a kernel.
KEPT_VERSIONS = 8


def kernel_sources(namespace: dict) -> list[Path]:
    """The files whose contents a kernel module's compiled kernels depend on, sorted.

    ``namespace`` is the module's ``globals()``. Returned: its own file and the files of the
    modules of its top-level package that it names (a module, or the module of a function,
    class, kernel or object it holds), and, through each of those modules that holds compiled
    kernels, the files that module names in turn: numba builds a called kernel into its caller
    and freezes the module-level constants a kernel reads (``K.P_MAXWELL_K``). A constant
    imported by value (``from m import X``) names no module: the package's kernels read the
    constants of other modules through the module (``K.``), which this sees.
    """
    top = str(namespace.get("__name__", "")).partition(".")[0]
    files: set[Path] = set()
    visited: set[str] = set()

    def visit(ns: dict) -> None:
        visited.add(ns.get("__name__"))
        if ns.get("__file__"):
            files.add(Path(ns["__file__"]).resolve())
        for value in list(ns.values()):
            module = _module_of(value)
            if module is None or module.__name__ in visited or module.__name__.partition(".")[0] != top:
                continue
            if _holds_kernels(module):
                visit(vars(module))
            else:  # many names of one module: looked at once
                visited.add(module.__name__)
                if getattr(module, "__file__", None):
                    files.add(Path(module.__file__).resolve())

    visit(namespace)
    return sorted(files)


def _module_of(value: object) -> types.ModuleType | None:
    """The module ``value`` is, or that defines it (a kernel's: its Python function's)."""
    if isinstance(value, types.ModuleType):
        return value
    try:
        name = getattr(getattr(value, "py_func", value), "__module__", None)
    except Exception:  # an object whose attribute lookup raises names no module
        return None
    return sys.modules.get(name) if isinstance(name, str) else None


def _holds_kernels(module: types.ModuleType) -> bool:
    from numba.core.dispatcher import Dispatcher

    return any(isinstance(v, Dispatcher) and getattr(v.py_func, "__module__", None) == module.__name__
               for v in list(vars(module).values()))


def sources_key(namespace: dict) -> str | None:
    """SHA-256 (hex) of the files :func:`kernel_sources` lists, each with its path inside the
    top-level package (a checkout and an installed copy of the same sources have the same key);
    None for a module outside a package."""
    name = str(namespace.get("__name__", ""))
    package = sys.modules.get(name.partition(".")[0])
    roots = getattr(package, "__path__", None)
    if not roots:  # a module outside a package
        return None
    root = Path(list(roots)[0]).resolve()
    digest = hashlib.sha256()
    for path in kernel_sources(namespace):
        try:
            inside = path.relative_to(root).as_posix()
        except ValueError:  # another copy of the package on the path: not this one's sources
            return None
        digest.update(inside.encode() + b"\0" + path.read_bytes() + b"\0")
    return digest.hexdigest()


def kernel_cache_root() -> Path:
    """The folder holding the kernel modules' cache folders: under ``NUMBA_CACHE_DIR`` where set
    (or where :func:`cache_available` set a private one), else in the user's cache."""
    from numba.core import config

    if config.CACHE_DIR:
        return Path(config.CACHE_DIR) / "droptower-kernels"
    import platformdirs

    return Path(platformdirs.user_cache_dir("droptower", appauthor=False)) / "numba"


def compile_once_across_processes(namespace: dict) -> None:
    """Give every cached numba dispatcher in ``namespace`` (a module's ``globals()``, called at
    the module's end) the package's cache: keyed on the module's sources (:func:`sources_key`,
    in a folder of :func:`kernel_cache_root`), and letting one process at a time compile a
    kernel: a process that finds no cached build waits while another process compiles the same
    function, then loads that build from the cache.

    numba writes its cache only after compiling, so processes started together (the test suite's
    workers, a campaign's) that reach a kernel no cache holds yet each compiled it in full,
    ~10 s of CPU per large kernel. The lock is an advisory lock on a file beside the cache index
    (``fcntl.flock``: released when its holder exits); where there is no ``fcntl`` (Windows)
    processes do not wait for each other. A module outside a package, or a cache folder that is
    not writable, is cached where numba would cache it. The compiled code is numba's, unchanged.
    """
    from numba.core.caching import FunctionCache
    from numba.core.registry import CPUDispatcher

    for value in namespace.values():
        if isinstance(value, CPUDispatcher) and type(getattr(value, "_cache", None)) is FunctionCache:
            value._cache = _compile_once_cache_class()(value.py_func)


def _sources_locator_class() -> type:
    """numba's cache locator for a kernel of a package: the folder named by the module and its
    :func:`sources_key`, which is also the source stamp numba checks a cached build against."""
    from numba.core.caching import _CacheLocator

    keys: dict[str, str | None] = {}  # module name -> key, computed once per process

    class SourcesLocator(_CacheLocator):
        def __init__(self, py_func, folder: Path, key: str) -> None:
            self._lineno = py_func.__code__.co_firstlineno
            self._folder, self._key = folder, key

        def get_cache_path(self) -> str:
            return str(self._folder)

        def get_source_stamp(self) -> str:
            return self._key

        def get_disambiguator(self) -> str:
            return str(self._lineno)

        @classmethod
        def from_function(cls, py_func, py_file):
            namespace = py_func.__globals__
            name = namespace.get("__name__")
            if name not in keys:
                try:
                    keys[name] = sources_key(namespace)
                except OSError:  # a source that cannot be read: numba's own places
                    keys[name] = None
            key = keys[name]
            if key is None:
                return None
            folder = kernel_cache_root() / f"{name}-{key[:16]}"
            if not folder.is_absolute():  # no home to expand "~" to: numba's own places
                return None
            new = not folder.exists()
            self = cls(py_func, folder, key)
            try:
                self.ensure_cache_path()
            except OSError:  # not writable: numba's own places
                return None
            if new:
                _prune(folder)
            return self

    return SourcesLocator


def _prune(folder: Path) -> None:
    """Remove the cache folders of ``folder``'s module beyond the :data:`KEPT_VERSIONS` most
    recently changed (a folder another process removes meanwhile is skipped)."""
    import shutil

    prefix = folder.name[:folder.name.rindex("-") + 1]
    siblings = []
    for path in folder.parent.glob(prefix + "*"):
        try:
            if path.is_dir() and len(path.name) == len(folder.name):
                siblings.append((path.stat().st_mtime, path))
        except OSError:
            continue
    for _, path in sorted(siblings, reverse=True)[KEPT_VERSIONS:]:
        if path != folder:
            shutil.rmtree(path, ignore_errors=True)


@functools.cache
def _compile_once_cache_class() -> type:
    """The cache class (it subclasses numba's, so it is built when first used: importing this
    module imports no numba)."""
    import time

    try:
        import fcntl
    except ImportError:  # no flock (Windows): processes do not wait for each other
        fcntl = None

    from numba.core import event as numba_event
    from numba.core.caching import FunctionCache

    class SourcesKeyedImpl(FunctionCache._impl_class):
        """numba's implementation of a function's cache, looking first in the sources' folder."""

        _locator_classes = [_sources_locator_class(), *FunctionCache._impl_class._locator_classes]

    class CompileOnceCache(FunctionCache):
        """numba's per-function cache, in the sources' folder; a miss takes the function's compile
        lock (until the build is saved) and looks again once it has it."""

        _impl_class = SourcesKeyedImpl
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
            if fcntl is None:
                return False
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

