"""A fresh process imports only what its command uses (docs/conventions.md, docs/benchmarks.md): reading and
extracting a log loads no numba, scipy.signal, scipy.optimize, pandas or pymunk until a step needs
them, so a lab that runs the extractor per file from its own scripts does not pay for them.

Guarded by what a fresh interpreter holds in ``sys.modules``, not by timing (the machine's load
would make a timed test flaky); ``benchmarks/bench_fresh.py`` measures the times."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
HEAVY = ("numba", "scipy.signal", "scipy.optimize", "scipy.stats", "pandas", "pymunk", "matplotlib", "pydantic")


def _fresh(code: str) -> dict:
    """Run ``code`` in a fresh interpreter on this checkout; it prints one JSON object."""
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO, timeout=120,
                          env={**os.environ, "PYTHONPATH": str(REPO)})
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1])


def _loaded(names: tuple[str, ...] = HEAVY) -> str:
    return f"[m for m in {names!r} if m in sys.modules]"


#: What each light entry point may not load, in the order one fresh interpreter runs them (below).
LIGHT = (("import droptower.extract", HEAVY),
         ("import droptower; droptower.extract_file; droptower.ExtractSettings", HEAVY),
         ("from droptower.io import read_any, map_channels, DropSignals", HEAVY),
         ("import droptower.damped_cosine, droptower.sdof", HEAVY),
         # droptower.rig.load_rig (every command that reads logs with a rig) and the decay fit's cache module
         ("from droptower.rig import load_rig; load_rig('rapp2022'); import droptower.rheology.numba_cache",
          ("pymunk", "numba", "droptower.rheology.coupling", "droptower.rig.simulate")))
#: ``identify --from-drop-tests`` (the model route): its modules, the servo bench's evaluation and
#: the noise floor's smoothing among them
DROP_TEST_ROUTE = ("import droptower.cli.identify_cmd, droptower.cli.identify_drops_cmd, droptower.identify.drop_campaign, "
                   "droptower.identify.dropreport, droptower.identify.noise, droptower.servo.evaluate, "
                   "droptower.servo.histories")


def test_light_entry_points_load_no_heavy_package_and_a_fit_loads_its_kernels_on_first_use() -> None:
    """One fresh interpreter runs each entry point after those before it, the lightest first, and
    lists after each what it may not load. ``sys.modules`` only grows, so what is loaded after a
    statement and those before it includes all that the statement loads alone: an empty list
    clears the statement as if it had run alone (and the first list that is not empty names the
    statement that pulled a package in).

    - The extractor's modules import none of the heavy packages: each is imported where it is
      used (scipy.signal for the angle-only drop finder, the decay fit's kernels when a fit runs,
      MINPACK where the compiled fit gives up, pandas for conditions tables and written tables).
    - Reading a rig file loads neither pymunk nor the compiled coupling; the decay fit's cache
      module loads no coupling.
    - The first fit imports the compiled kernels (from the package's cache) and gives the decay
      it was made from; later fits reuse them (numba compiles or loads each kernel once per process).
    - The model route's modules load neither scipy.signal nor matplotlib until a step needs them
      (a servo record smoothed, a plot drawn)."""
    code = ["import sys, json", "said = []"]
    for statement, names in LIGHT:
        code += [statement, f"said.append({_loaded(names)})"]
    code += ["import numpy as np", "from droptower.damped_cosine import fit_decay",
             "before = 'droptower.damped_cosine_kernels' in sys.modules",
             "t = np.arange(4000) / 38400.0; y = 0.01 * np.exp(-20.0 * t) * np.cos(200.0 * t - 0.3)",
             "fits = [fit_decay(t, y, 210.0, 15.0) for _ in range(3)]",
             "from droptower.damped_cosine_kernels import levenberg_marquardt as lm",
             "fit = {'before': before, 'params': [float(v) for v in fits[-1].params], 'signatures': len(lm.signatures)}",
             DROP_TEST_ROUTE, f"route = {_loaded(('scipy.signal', 'matplotlib'))}",
             "print(json.dumps({'light': said, 'fit': fit, 'route': route}))"]
    out = _fresh("\n".join(code))
    assert dict(zip([s for s, _ in LIGHT], out["light"])) == {s: [] for s, _ in LIGHT}
    assert out["fit"]["before"] is False and out["fit"]["signatures"] == 1
    assert out["fit"]["params"] == pytest.approx([0.01, 20.0, 200.0, 0.3], rel=1e-9)
    assert out["route"] == []


def test_simulate_keeps_its_name_when_its_module_is_imported() -> None:
    """``droptower.rig`` imports its names on first use; importing the module
    ``droptower.rig.simulate`` (as the campaign does) leaves ``droptower.rig.simulate`` and
    ``droptower.simulate`` the function, as when the package imported it eagerly."""
    out = _fresh("import json, droptower, droptower.rig.simulate as module; import droptower.rig as rig; "
                 "from droptower.rig import simulate; "
                 "print(json.dumps([callable(simulate), simulate is rig.simulate, droptower.simulate is simulate, "
                 "type(module).__name__, sorted(set(rig.__all__) - set(dir(rig)))]))")
    assert out == [True, True, True, "function", []]
