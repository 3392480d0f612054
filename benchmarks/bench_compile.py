"""numba's cold compile cost of the package's kernels: what a fresh clone or CI pays once.

    python benchmarks/bench_compile.py [--json PATH]

Runs, in a fresh process with an empty numba cache (``NUMBA_CACHE_DIR`` set to a new temporary
folder: the cache beside the sources is neither read nor touched), the calls that compile every
kernel the test suite reaches: a coupling's single step, histories of one row and of a large
batch, the lever's free decay (one row and a large batch), a decay fit, a drop on the rig (free
flight) and the filled-rubber family's stiffening closed form. Prints each top-level compilation (wall and
CPU; the kernels it calls are compiled within it and counted there) and the total.

Baseline, measured in the same process first (after numba's one-time set-up): the compilation of
a four-line numba function, numba's fixed cost per compiled function; each kernel's CPU time is
also printed as a ratio to it.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from timing import json_option, write_figures

REPO = Path(__file__).resolve().parents[1]

WORKLOAD = r'''
import json, sys, time
from numba.core import event as numba_event

records, depth = [], [0]

class Compilations(numba_event.Listener):
    def on_start(self, event):
        if depth[0] == 0:
            self.t0, self.c0 = time.perf_counter(), time.process_time()
        depth[0] += 1

    def on_end(self, event):
        depth[0] -= 1
        if depth[0] == 0:
            func = event.data["dispatcher"].py_func
            records.append({"function": f"{func.__module__}.{func.__qualname__}",
                            "wall_s": time.perf_counter() - self.t0, "cpu_s": time.process_time() - self.c0})

numba_event.register("numba:compile", Compilations())

import numpy as np
from numba import njit

def baseline(x):
    s = 0.0
    for v in x:
        s += v
    return s

njit(nogil=True, error_model="numpy")(lambda x: x)(1.0)  # numba's one-time set-up, not counted
records.clear()
njit(nogil=True, error_model="numpy")(baseline)(np.ones(3))
import droptower as dt
from droptower.damped_cosine import fit_decay
from droptower.identify.families import filled_rubber
from droptower.rig.config import load_rig
from droptower.rig.predictions import free_decay
from droptower.rig.preload import Pretwist
from droptower.rig.simulate import DropTest, simulate

coupling, h = dt.load_coupling("rapp2022_nr60"), 1 / 38400
x = np.radians(0.5) * np.sin(np.linspace(0.0, 20.0, 400))
coupling.step(coupling.new_state(), 1e-3, h)
for n in (1, 16):  # one row, and a batch large enough to be spread over the cores
    coupling.simulate(np.tile(x, (n, 1)), h, state=coupling.new_state(n))
    free_decay(coupling, np.full(n, 0.359), np.full(n, 3.0),
               Pretwist(np.zeros(n), np.zeros(n), coupling.new_state(n)), h, 0.01)
t = np.linspace(0.0, 0.2, 2000)
fit_decay(t, np.exp(-8.0 * t) * np.cos(2 * np.pi * 40.0 * t), 2 * np.pi * 40.0, 8.0)
simulate(load_rig("rapp2022"), coupling, [DropTest(0.359, 2.0, 0.5)], duration_s=0.02)
filled_rubber.stiffening_maxwell_stiffness(3000.0, 1e5, 5.0, np.radians([0.5, 1.0]), np.array([50.0, 100.0]))
json.dump(records, sys.stdout)
'''


def measure() -> list[dict]:
    """The top-level compilations of the workload in a fresh process on an empty cache."""
    with tempfile.TemporaryDirectory(prefix="bench-compile-") as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache, "MPLBACKEND": "Agg"}
        run = subprocess.run([sys.executable, "-c", WORKLOAD], cwd=REPO, env=env, capture_output=True, text=True,
                             check=False)
    if run.returncode != 0:
        raise SystemExit(run.stderr)
    return json.loads(run.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    json_option(parser)
    args = parser.parse_args()
    records = measure()
    base = next(r for r in records if r["function"].endswith(".baseline"))
    kernels = [r for r in records if r is not base]
    print(f"baseline (a four-line numba function): {base['wall_s']:.2f} s wall, {base['cpu_s']:.2f} s CPU")
    for r in kernels:
        print(f"  {r['function']:<60} {r['wall_s']:6.2f} s wall {r['cpu_s']:6.2f} s CPU "
              f"({r['cpu_s'] / base['cpu_s']:5.1f}x baseline)")
    total_cpu = sum(r["cpu_s"] for r in kernels)
    total_wall = sum(r["wall_s"] for r in kernels)
    print(f"total: {len(kernels)} compilations, {total_wall:.1f} s wall, {total_cpu:.1f} s CPU "
          f"({total_cpu / base['cpu_s']:.0f}x baseline)")
    write_figures(args.json, "bench_compile", {
        "baseline_cpu_s": base["cpu_s"], "total_cpu_s": total_cpu, "total_wall_s": total_wall,
        "total_over_baseline": total_cpu / base["cpu_s"],
        "kernels_cpu_s": {r["function"]: r["cpu_s"] for r in kernels}})


if __name__ == "__main__":
    main()
