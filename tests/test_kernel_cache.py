"""The compiled kernels' cache is keyed on the sources they are built from
(``droptower.rheology.numba_cache``): a kernel is rebuilt when a file it depends on changes, not
only its own, and another copy of the same sources (an installed copy, a reinstall) loads it."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path


from droptower.rheology import numba_cache

REPO = Path(__file__).resolve().parents[1]

# a package whose kernel (outer.twice) is built around another module's kernel and constant
PACKAGE = {
    "__init__.py": "",
    "inner.py": "from numba import njit\nfrom droptower.rheology.numba_cache import compile_once_across_processes\n"
                "SCALE = 2.0\n\n@njit(cache=True)\ndef scaled(x):\n    return SCALE * x\n\n"
                "compile_once_across_processes(globals())\n",
    "outer.py": "from numba import njit\nfrom droptower.rheology.numba_cache import compile_once_across_processes\n"
                "from kpkg import inner\n\n@njit(cache=True)\ndef twice(x):\n    return inner.scaled(x)\n\n"
                "compile_once_across_processes(globals())\n",
    "unrelated.py": "VALUE = 1\n",
}
RUN = """
import json, sys
sys.path.insert(0, sys.argv[1])
from kpkg import outer
value = outer.twice(1.0)
stats = outer.twice.stats
print(json.dumps({"value": value, "hits": sum(stats.cache_hits.values()), "misses": sum(stats.cache_misses.values()),
                  "folder": outer.twice._cache.cache_path}))
"""


def _run(code: str, *args: str, cache: Path) -> dict:
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache)}
    proc = subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True, env=env, timeout=300,
                          cwd=REPO)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout.splitlines()[-1])


def test_a_kernel_is_rebuilt_when_a_module_it_is_built_from_changes(tmp_path: Path) -> None:
    """numba's own cache is keyed on the kernel's file alone: after ``inner.py``'s constant
    changed, ``outer.twice`` (which inlines ``inner.scaled``) still returned the old value from
    its cache. Keyed on the sources, it is rebuilt; a change to a file it does not depend on
    leaves its build in place; old versions' folders beyond the kept number are removed."""
    package = tmp_path / "src" / "kpkg"
    package.mkdir(parents=True)
    for name, text in PACKAGE.items():
        (package / name).write_text(text)
    cache = tmp_path / "cache"
    root = cache / "droptower-kernels"
    root.mkdir(parents=True)
    old = []
    for i in range(numba_cache.KEPT_VERSIONS + 2):  # earlier versions' folders, oldest first
        folder = root / f"kpkg.outer-{i:016x}"
        folder.mkdir()
        os.utime(folder, (time.time() - 1000 + i, time.time() - 1000 + i))
        old.append(folder)

    first = _run(RUN, str(package.parent), cache=cache)
    assert first["value"] == 2.0 and first["misses"] == 1 and first["hits"] == 0
    kept = sorted(p.name for p in root.glob("kpkg.outer-*"))
    assert len(kept) == numba_cache.KEPT_VERSIONS and Path(first["folder"]).name in kept
    assert all(p.name in kept for p in old[-(numba_cache.KEPT_VERSIONS - 1):])  # the newest old ones stay

    (package / "unrelated.py").write_text("VALUE = 2\n")
    again = _run(RUN, str(package.parent), cache=cache)
    assert again == {**first, "misses": 0, "hits": 1}  # loaded from the same folder

    (package / "inner.py").write_text(PACKAGE["inner.py"].replace("SCALE = 2.0", "SCALE = 3.0"))
    changed = _run(RUN, str(package.parent), cache=cache)
    assert changed["value"] == 3.0 and changed["misses"] == 1 and changed["folder"] != first["folder"]


def test_the_sources_of_a_kernel_module_are_the_modules_it_names() -> None:
    """The rig's lever kernel is built around the core's step and reads its slot constants: its
    key covers ``rheology/kernels.py``; the core's key does not cover the rig."""
    from droptower.rig import lever_decay as lever
    from droptower.rheology import kernels

    root = Path(kernels.__file__).resolve().parents[1]
    lever_files = {p.relative_to(root).as_posix() for p in numba_cache.kernel_sources(vars(lever))}
    kernel_files = {p.relative_to(root).as_posix() for p in numba_cache.kernel_sources(vars(kernels))}
    assert {"rig/lever_decay.py", "rheology/kernels.py"} <= lever_files
    assert "rheology/kernels.py" in kernel_files and "rig/lever_decay.py" not in kernel_files
    assert numba_cache.sources_key(vars(lever)) != numba_cache.sources_key(vars(kernels))
    assert numba_cache.sources_key({"__name__": "plain_module"}) is None  # outside a package: numba's places


LOAD = """
import json, sys
sys.path.insert(0, sys.argv[1])
import numpy as np
from droptower import damped_cosine as decayfit, damped_cosine_kernels
t = np.linspace(0.0, 0.5, 400)
fit = decayfit.fit_decay(t, np.exp(-3.0 * t) * np.sin(2 * np.pi * 20.0 * t), 2 * np.pi * 20.0, 3.0)
stats = damped_cosine_kernels.levenberg_marquardt.stats
print(json.dumps({"file": decayfit.__file__, "fit": [float(v) for v in fit.params],
                  "hits": sum(stats.cache_hits.values()), "misses": sum(stats.cache_misses.values())}))
"""


def test_another_copy_of_the_package_loads_the_kernel_this_one_compiled(tmp_path: Path) -> None:
    """A copy of the package elsewhere (as ``pip install .`` makes beside a checkout) compiles a
    kernel; this checkout then loads that build instead of compiling its own."""
    copy = tmp_path / "copy"
    shutil.copytree(REPO / "droptower", copy / "droptower", ignore=shutil.ignore_patterns("__pycache__"))
    cache = tmp_path / "cache"
    there = _run(LOAD, str(copy), cache=cache)
    here = _run(LOAD, str(REPO), cache=cache)
    assert Path(there["file"]).is_relative_to(copy) and Path(here["file"]).is_relative_to(REPO)
    assert there["misses"] == 1 and here == {**there, "file": here["file"], "hits": 1, "misses": 0}


def test_kernel_modules_read_other_modules_constants_through_the_module() -> None:
    """A kernel freezes the module-level constants it reads; a constant imported by value
    (``from droptower.x import LIMIT``) names no module, so its file would be missing from the
    kernel's key (:func:`~droptower.rheology.numba_cache.kernel_sources`) and an edit of it would
    leave the build stale. The package's kernel modules import no constant so."""
    import ast

    offenders = []
    for path in sorted((REPO / "droptower").rglob("*.py")):
        text = path.read_text()
        if "@njit" not in text:
            continue
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("droptower"):
                offenders += [f"{path.relative_to(REPO)}: {a.name}" for a in node.names if a.name.isupper()]
    assert offenders == []
