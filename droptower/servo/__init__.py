"""The virtual servo-hydraulic bench: imposed angle histories, lab-style evaluation, grids.

- :mod:`.histories`: sine with preload offset, sweeps, dual-frequency, steps, ramps, random;
- :mod:`.evaluate`: steady-state cycles -> K', K'', |K*|, loss angle, W_D, psi (the elastoslide paper, eq. 6,
  DIN 740-2 style), and the drop-tower-equivalent damping ratio (docs/theory.md#damping-measures);
- :mod:`.bench`: :func:`run_grid` drives a coupling over amplitudes x frequencies, batched;
  :func:`run_records` gives the raw time records of the same runs;
- :mod:`.records`: raw servo time records (files, any dialect the readers take) evaluated as
  the lab's bench software does: blocks, steady cycles, K', K'', loss factor and their scatter
  (:func:`read_servo_signals` reads one, with a sample interval where it has no time channel;
  identification reads its records through it too);
- :mod:`.plots`: hysteresis loops.
"""
from droptower.servo.bench import BenchRecord, BenchResult, run_bench, run_grid, run_records
from droptower.servo.evaluate import CycleEvaluation, drop_tower_equivalent_damping_ratio, evaluate_cycles, evaluate_history
from droptower.servo.records import RecordBlock, evaluate_record, evaluate_records, find_blocks, read_servo_signals

__all__ = ["BenchRecord", "BenchResult", "run_records", "CycleEvaluation", "drop_tower_equivalent_damping_ratio", "evaluate_cycles",
           "evaluate_history", "run_bench", "run_grid", "RecordBlock", "evaluate_record", "evaluate_records", "find_blocks",
           "read_servo_signals"]
