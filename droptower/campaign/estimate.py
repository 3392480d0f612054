"""Time and disk of a campaign before it runs (:func:`~droptower.campaign.estimate_campaign`, which the ``campaign`` command also offers).

The first chunk of the plan is run for real (simulated, logged, read back and extracted) in a
temporary folder; its CPU per test and the bytes it wrote per test (log and record) are scaled
to the tests still to run. Wall time assumes the workers share the cores evenly: tests x CPU
per test / min(workers, cores). Chunk size, record
length and log format are the campaign's, so the sample costs what the campaign's tests cost;
conditions differ little in cost (every test steps the same number of samples).
"""
from __future__ import annotations

import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from droptower.campaign.chunk import ChunkTask, run_chunk
from droptower.campaign.folder import layout_for
from droptower.campaign.spec import PLAN_COLUMNS, CampaignSpec

#: Bytes of the results table (Parquet and CSV) per test, measured on the Table-2 campaign.
RESULTS_BYTES_PER_TEST = 1500


@dataclass(frozen=True)
class Estimate:
    """What a campaign will cost: tests (all, to run), the sample it was measured on (tests,
    CPU s), CPU per test (s), workers and cores used, wall time (s), bytes per test (log,
    record) and the disk the tests to run will take (bytes, results table included)."""

    n_tests: int
    to_run: int
    sample_tests: int
    sample_cpu_s: float
    cpu_per_test_s: float
    workers: int
    cores: int
    wall_s: float
    log_bytes_per_test: float
    record_bytes_per_test: float
    disk_bytes: float

    def lines(self) -> list[str]:
        """The estimate as text (one figure per line, units in the text)."""
        per_test_kb = (self.log_bytes_per_test + self.record_bytes_per_test) / 1e3
        return [
            f"{self.to_run} of {self.n_tests} tests to run; measured on {self.sample_tests} test(s) "
            f"(one chunk, {self.sample_cpu_s:.2f} s CPU): {1e3 * self.cpu_per_test_s:.1f} ms CPU per test",
            f"time: about {_duration(self.wall_s)} on {self.workers} worker(s) sharing {self.cores} core(s) "
            f"(more if other jobs load the machine)",
            f"disk: about {self.disk_bytes / 1e6:.1f} MB ({per_test_kb:.1f} kB per test: log "
            f"{self.log_bytes_per_test / 1e3:.1f} kB, record {self.record_bytes_per_test / 1e3:.1f} kB; "
            f"results table included)",
        ]


def _duration(seconds: float) -> str:
    if seconds < 120:
        return f"{seconds:.0f} s"
    if seconds < 7200:
        return f"{seconds / 60:.1f} min"
    return f"{seconds / 3600:.1f} h"


def estimate(spec: CampaignSpec, workers: int, cores: int, to_run: int | None = None) -> Estimate:
    """Run the plan's first chunk in a temporary folder and scale it to ``to_run`` tests (None:
    all) on ``workers`` workers sharing ``cores`` cores."""
    n = len(spec.tests)
    to_run = n if to_run is None else to_run
    rows = spec.chunks()[0]
    plan = spec.tests[list(PLAN_COLUMNS)].to_dict(orient="records")
    with tempfile.TemporaryDirectory(prefix="droptower-estimate-") as tmp:
        def task(folder: str, chunk: list[int]) -> ChunkTask:
            layout = layout_for(Path(tmp) / folder, spec)
            layout.records.mkdir(parents=True)
            layout.logs.mkdir()
            return ChunkTask(index=0, layout=layout, plan=tuple(plan[i] for i in chunk), todo=(True,) * len(chunk),
                             rig=spec.rig, coupling=spec.coupling, duration_s=spec.duration_s,
                             log_format=spec.log_format, window=spec.window)

        run_chunk(task("warm-up", [int(rows[0])]))  # compiled code loaded, as in a running campaign
        sample = task("sample", [int(i) for i in rows])
        t0 = time.process_time()
        run_chunk(sample)
        cpu = time.process_time() - t0
        layout = sample.layout
        log_bytes = sum(p.stat().st_size for p in layout.logs.iterdir())
        record_bytes = sum(p.stat().st_size for p in layout.records.iterdir())
    k = len(rows)
    per_test = cpu / k
    share = max(1, min(workers, cores))
    wall = to_run * per_test / share
    return Estimate(n_tests=n, to_run=to_run, sample_tests=k, sample_cpu_s=cpu, cpu_per_test_s=per_test,
                    workers=workers, cores=cores, wall_s=wall, log_bytes_per_test=log_bytes / k,
                    record_bytes_per_test=record_bytes / k,
                    disk_bytes=to_run * (log_bytes / k + record_bytes / k + RESULTS_BYTES_PER_TEST))
