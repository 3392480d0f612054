"""One chunk of a campaign, as a worker runs it: simulate -> log -> read back and extract -> record.

A chunk is a fixed run of consecutive tests of the plan, simulated by one batched
:func:`droptower.rig.simulate.simulate` call (one pymunk space). Each test's log is then
written in the project's log format (compact Parquet: float32 channels, zstd; or CSV), read
back from disk and evaluated by the same code that evaluates real logs
(:func:`droptower.extract.files.extract_file`, as ``droptower extract``), and its result record
written (one line of JSON). The worker writes the files itself, so the main process ships
no signals; with a Dask cluster the folder must be reachable by the workers under the same
path (a shared file system).

A chunk interrupted midway is simulated again as a whole on resume (each test keeps its place
in its batch, so its physics is bit for bit the same), but only its unfinished tests are
written: a finished test's log and record are never rewritten.
"""
from __future__ import annotations

import resource
import sys
import time
from dataclasses import dataclass, field
from typing import Any

from droptower.campaign.folder import Layout, write_json
from droptower.errors import DroptowerError


@dataclass(frozen=True)
class ChunkTask:
    """Everything a worker needs for one chunk (picklable).

    plan: the chunk's rows of the plan (dicts of :data:`~droptower.campaign.spec.PLAN_COLUMNS`);
    todo: per row, whether its log and record are still to be written.
    """

    index: int
    layout: Layout
    plan: tuple[dict[str, Any], ...]
    todo: tuple[bool, ...]
    rig: Any
    coupling: Any
    duration_s: float
    log_format: str
    window: str


@dataclass
class ChunkOutcome:
    """What a chunk did: per written test its status; CPU time per phase (s: simulation;
    sensor sampling and log writing; reading back, extraction and the record); the worker's
    peak resident memory (MB). CPU time of the worker thread, not wall time: workers share
    the cores."""

    index: int
    status: dict[int, dict[str, Any]] = field(default_factory=dict)
    simulate_cpu_s: float = 0.0
    write_cpu_s: float = 0.0
    extract_cpu_s: float = 0.0
    peak_rss_mb: float = 0.0


def peak_rss_mb(who: int = resource.RUSAGE_SELF) -> float:
    """Peak resident memory (MB) of this process (or, with RUSAGE_CHILDREN, of its largest
    finished child)."""
    peak = resource.getrusage(who).ru_maxrss
    return peak / 2**20 if sys.platform == "darwin" else peak / 2**10  # bytes on macOS, KiB on Linux


def _record(row: dict[str, Any], log_file: str | None, status: str, result: dict[str, Any] | None, error: str | None,
            warnings: list[str]) -> dict[str, Any]:
    return {**row, "status": status, "log_file": log_file, "result": result, "error": error,
            "simulation_warnings": warnings}


def run_chunk(task: ChunkTask) -> ChunkOutcome:
    """Simulate the chunk, then write, read back and extract each unfinished test."""
    from droptower.extract.files import Settings, extract_file
    from droptower.extract.window import Window
    from droptower.rig.simulate import DropTest, simulate

    out = ChunkOutcome(task.index)
    layout = task.layout
    tests = [DropTest(float(r["inertia_kgm2"]), float(r["drop_mass_kg"]), float(r["drop_height_m"]),
                      float(r["preload_nm"]), int(r["repeat"]), int(r["seed"])) for r in task.plan]
    t0 = time.thread_time()
    try:
        results = simulate(task.rig, task.coupling, tests, task.duration_s)
    except DroptowerError as exc:  # the plan's fault (e.g. a preload the coupling cannot hold): final
        for row, todo in zip(task.plan, task.todo):
            if todo:
                test_id = int(row["test_id"])
                write_json(layout.record(test_id), _record(row, None, "failed", None, f"simulation: {exc.message}", []),
                           indent=None)
                out.status[test_id] = {"status": "failed", "error": f"simulation: {exc.message}", "log_file": None}
        out.simulate_cpu_s = time.thread_time() - t0
        out.peak_rss_mb = peak_rss_mb()
        return out
    out.simulate_cpu_s = time.thread_time() - t0

    settings = Settings(defaults={"lever_length_m": task.rig.lever_length_m},
                        sensor_radius_m=task.rig.sensors.laser.radius_m, window=Window.parse(task.window))
    for row, result, todo in zip(task.plan, results, task.todo):
        if not todo:
            continue
        test_id = int(row["test_id"])
        log_file = layout.log_file(test_id, task.log_format)
        t1 = time.thread_time()
        result.write_log(layout.root / log_file, compact=task.log_format == "parquet")  # CSV: full text
        t2 = time.thread_time()
        try:
            _, extracted = extract_file(layout.root / log_file, settings)
            record = _record(row, log_file, "done", extracted.to_dict(), None, result.warnings)
        except DroptowerError as exc:  # the log is named by log_file: the message leaves out the folder's path
            reason = ": ".join(part for part in (exc.where, exc.problem) if part)
            record = _record(row, log_file, "failed", None, reason, result.warnings)
        write_json(layout.record(test_id), record, indent=None)
        out.status[test_id] = {"status": record["status"], "error": record["error"], "log_file": log_file}
        out.write_cpu_s += t2 - t1
        out.extract_cpu_s += time.thread_time() - t2
    out.peak_rss_mb = peak_rss_mb()
    return out
