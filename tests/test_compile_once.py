"""Processes that reach a kernel no cache holds compile it once between them
(``droptower.rheology.numba_cache.compile_once_across_processes``): the others wait and load it."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("fcntl", reason="the compile lock is POSIX's flock")

KERNEL = '''
import numpy as np
from numba import njit

@njit(cache=True)
def kernel(x):
    total = 0.0
    for i in range(x.size):
        total += np.sin(x[i]) * np.cos(x[i]) + np.sqrt(abs(x[i])) + np.exp(-x[i] * x[i])
    return total
'''

# "second" imports everything and waits for "first" to miss the cache; "first", once "second" is
# ready, calls the kernel, misses, says so (a file) and holds on 1 s before compiling (a window a thousand times what the other needs to reach its cache). Each prints numba's count of cache misses (compilations).
RACE = '''
import sys, time
from pathlib import Path
import numpy as np
folder, role, mode = Path(sys.argv[1]), sys.argv[2], sys.argv[3]
sys.path.insert(0, str(folder))
import kernel_module
if mode == "locked":
    from droptower.rheology.numba_cache import compile_once_across_processes
    compile_once_across_processes(vars(kernel_module))
cache = kernel_module.kernel._cache
if role == "first":
    load = cache.load_overload
    def load_then_linger(sig, context):
        data = load(sig, context)
        if data is None:
            (folder / "first-missed").touch()
            time.sleep(1.0)
        return data
    cache.load_overload = load_then_linger
    while not (folder / "second-ready").exists():
        time.sleep(0.001)
else:
    (folder / "second-ready").touch()
    while not (folder / "first-missed").exists():
        time.sleep(0.001)
assert kernel_module.kernel(np.linspace(0.0, 1.0, 11)) > 0
print(sum(kernel_module.kernel.stats.cache_misses.values()))
'''


def _start(folder: Path, locked: bool) -> list[subprocess.Popen]:
    folder.mkdir()
    (folder / "kernel_module.py").write_text(KERNEL)
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}  # numba caches in folder/__pycache__
    return [subprocess.Popen([sys.executable, "-c", RACE, str(folder), role, "locked" if locked else "plain"],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
            for role in ("first", "second")]


def _misses(runs: list[subprocess.Popen]) -> list[int]:
    outs = [run.communicate(timeout=600) for run in runs]
    assert all(run.returncode == 0 for run in runs), [err for _, err in outs]
    return [int(out.split()[-1]) for out, _ in outs]


def test_processes_that_reach_an_uncached_kernel_together_compile_it_once(tmp_path: Path) -> None:
    """Without the lock both processes miss the cache and compile (the race this removes); with it,
    the second waits while the first compiles and loads the build from the cache, which holds it once."""
    plain, locked = _start(tmp_path / "plain", locked=False), _start(tmp_path / "locked", locked=True)
    assert _misses(plain) == [1, 1]
    assert _misses(locked) == [1, 0]
    index = list((tmp_path / "locked" / "__pycache__").glob("kernel_module.kernel-*.nbi"))
    assert len(index) == 1 and len(list((tmp_path / "locked" / "__pycache__").glob("kernel_module.kernel-*.nbc"))) == 1


def test_the_dispatchers_of_the_package_share_their_compilations() -> None:
    from numba.core.caching import FunctionCache

    from droptower import damped_cosine_kernels
    from droptower.rheology import kernels as K
    from droptower.rig import flight, lever_decay as lever

    for module in (K, lever, flight, damped_cosine_kernels):
        dispatchers = [v for v in vars(module).values() if hasattr(v, "_cache") and hasattr(v, "py_func")]
        assert dispatchers, module.__name__
        for d in dispatchers:
            if K.CACHE:  # where no cache is writable there is nothing to share (compiled at every start)
                assert isinstance(d._cache, FunctionCache) and type(d._cache) is not FunctionCache, d


def test_a_compilation_that_fails_releases_its_lock(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A signature that does not type saves no build; its lock is released at once, so another
    process compiling the function does not wait for it."""
    import fcntl
    import importlib

    from numba.core.errors import TypingError

    from droptower.rheology.numba_cache import compile_once_across_processes

    (tmp_path / "failing_module.py").write_text(KERNEL)
    monkeypatch.syspath_prepend(str(tmp_path))
    module = importlib.import_module("failing_module")
    compile_once_across_processes(vars(module))
    with pytest.raises(TypingError):
        module.kernel("not an array")
    (lock,) = Path(module.kernel._cache.cache_path).glob("failing_module.kernel-*.lock")
    with open(lock, "a") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)  # raises BlockingIOError while it is held
