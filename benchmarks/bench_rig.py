"""Speed of the virtual drop tower.

    python benchmarks/bench_rig.py [--coupling rapp2022_nr60] [--workers 2] [--quick]

The reference coupling is the shipped ``rapp2022_nr60`` preset (spring + elastoslide with 32
elements, p = 7 + two Maxwell branches) on the shipped ``rapp2022`` rig (38.4 kHz output, two
internal steps per sample). Figures printed:

1. one test, 0.25 s after the impact (plus the 5 ms pre-trigger), case 2, 1 m, no preload:
   wall time, best of 3 (target <= 0.3 s);
2. the 450 tests of Table 2 (``rapp2022_table2``), 0.25 s each, batched, split over
   ``--workers`` processes: wall time (target <= 30 s on 2 cores), and the ratio of the
   time per test batched to the single test;
3. named baseline, measured in the same run: the bare pymunk scene of test 1 stepped as often
   with the coupling torque left out (``Space.step`` and the body reads only), and the ratio
   of test 1 to it: the cost of the coupling, the sampling and the bookkeeping.
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from droptower.rheology import load_coupling
from droptower.rig.config import load_doe, load_rig
from droptower.rig.scene import DropTowerScenes
from droptower.rig.simulate import DropTest, simulate
from timing import best_of, json_option, write_figures

DURATION_S = 0.25


def bare_pymunk(rig, steps: int) -> None:
    """The scene of test 1 without the coupling: what pymunk alone costs."""
    v1 = np.sqrt(2 * 9.81 * 1.0)
    scenes = DropTowerScenes(inertia_kgm2=np.array([0.359]), drop_mass_kg=np.array([2.0]), gap_m=np.array([0.02]),
                             start_velocity_m_per_s=np.array([v1]), lever_length_m=rig.lever_length_m,
                             restitution=rig.restitution, striker_radius_m=rig.simulation.striker_radius_m,
                             gravity_m_per_s2=rig.gravity_m_per_s2, dt_s=rig.dt_s,
                             solver_iterations=rig.simulation.solver_iterations, t0_s=0.0)
    pred = np.empty(1)
    for _ in range(steps):
        scenes.bodies.predict(rig.dt_s, [0.0], pred)
        scenes.space.step(rig.dt_s)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--coupling", default="rapp2022_nr60")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--quick", action="store_true", help="90 tests instead of 450 (a smoke run)")
    json_option(parser)
    args = parser.parse_args()

    rig = load_rig("rapp2022")
    coupling = load_coupling(args.coupling)
    single_test = [DropTest(0.359, 2.0, 1.0)]
    simulate(rig, coupling, single_test, duration_s=0.01)  # load the compiled kernels

    single = best_of(lambda: simulate(rig, coupling, single_test, duration_s=DURATION_S), 3)
    steps = int(round((rig.sensors.pre_trigger_s + DURATION_S) * rig.sensors.sample_rate_hz)) \
        * rig.simulation.steps_per_sample
    bare = best_of(lambda: bare_pymunk(rig, steps), 3)
    print(f"rig {rig.name}, coupling {coupling.name}: {rig.sensors.sample_rate_hz:g} Hz output, "
          f"{rig.simulation.steps_per_sample} internal steps per sample ({steps} steps per test)")
    print(f"1. one test, {DURATION_S} s:           {single:7.3f} s wall   (target <= 0.3 s)")
    print(f"3. baseline, bare pymunk scene:   {bare:7.3f} s wall   -> one test = {single / bare:.2f} x baseline")

    tests = load_doe("rapp2022_table2").tests()
    if args.quick:
        tests = tests.iloc[::5]
    t0 = time.perf_counter()
    results = simulate(rig, coupling, tests, duration_s=DURATION_S, workers=args.workers)
    batched = time.perf_counter() - t0
    per_test = batched / len(tests)
    print(f"2. {len(tests)} tests batched, {args.workers} worker(s): {batched:7.2f} s wall   (target <= 30 s for 450)"
          f"   {1e3 * per_test:.1f} ms per test = {per_test / single:.3f} x the single test")
    worst = max(r.energy_balance_error for r in results)
    print(f"   check: worst energy balance error {100 * worst:.3f} %, "
          f"{sum(r.double_impact for r in results)} double impacts")
    write_figures(args.json, "bench_rig", {
        "coupling": coupling.name, "single_test_s": single, "bare_pymunk_s": bare, "tests": len(tests),
        "workers": args.workers, "batched_s": batched, "batched_per_test_ms": 1e3 * per_test})


if __name__ == "__main__":
    main()
