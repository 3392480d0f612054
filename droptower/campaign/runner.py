"""Run a campaign: plan -> fixed chunks -> (simulate, log, extract) per chunk -> results table.

Resumable and loss-free: the folder's records say which tests are finished; only chunks with
unfinished tests run; the manifest is rewritten (atomically) at most every
:data:`MANIFEST_EVERY_S` seconds while chunks finish and once at the end (its per-test status
may lag behind the records, never the other way round: the records decide); the results
table is assembled from the records at the end of every run. Deterministic: chunks are fixed
by the plan (not by the number of workers), every test's noise comes from its own seed, so one
worker, two workers, a Dask cluster and an interrupted-then-resumed run write the same results.
"""
from __future__ import annotations

import resource
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd

from droptower.campaign.chunk import ChunkOutcome, ChunkTask, peak_rss_mb, run_chunk
from droptower.campaign.estimate import Estimate, estimate
from droptower.campaign.executors import SCHEDULER_TIMEOUT_S, DaskCluster, InProcess, local_cores, make_executor
from droptower.campaign.folder import (Layout, finished, finished_batches, folder_lock, layout_for, open_folder,
                                       saved_inputs, saved_settings, write_manifest)
from droptower.campaign.results import assemble_batches, write_results
from droptower.campaign.spec import PLAN_COLUMNS, CampaignSpec, prepare
from droptower.configs import DEFAULT_COUPLING, DEFAULT_DOE, DEFAULT_RIG
from droptower.errors import DroptowerError, WriteError

#: Seconds between two rewrites of the manifest during a run: it lists every test, so rewriting
#: it after each chunk would cost O(tests) per chunk, O(tests^2) per campaign.
MANIFEST_EVERY_S = 5.0


@dataclass
class CampaignRun:
    """What a run did.

    results: the results table (every finished test of the folder); failed: (test_id, error)
    of tests whose simulation or extraction failed (final, listed in the results); errors:
    chunks that crashed with an unexpected error in this run (their tests stay pending and are
    retried with ``resume=True``); pending: tests still unfinished; ran_tests: tests written in this
    run; executor: where the chunks ran; CPU time per phase summed over the workers (s), the
    wall time (s); peak memory (MB) of this process and of the largest worker; outputs: (path,
    what) of every file and folder the run wrote (the results tables, the logs, ``summary.csv``
    and Fig. 11 of Rapp et al. 2022 when the plan varies the preload).
    """

    spec: CampaignSpec
    root: Path
    executor: str
    results: pd.DataFrame
    failed: list[tuple[int, str]]
    errors: list[str]
    pending: int
    ran_tests: int
    wall_s: float
    simulate_cpu_s: float = 0.0
    write_cpu_s: float = 0.0
    extract_cpu_s: float = 0.0
    peak_rss_main_mb: float = 0.0
    peak_rss_worker_mb: float = 0.0
    warnings: list[str] = field(default_factory=list)
    outputs: list[tuple[Path, str]] = field(default_factory=list)

    @property
    def done(self) -> int:
        """Tests extracted."""
        return int((self.results["status"] == "done").sum()) if len(self.results) else 0

    def summary(self) -> str:
        """One line: the campaign, its tests extracted, failed and pending, this run's time."""
        n = len(self.spec.tests)
        return (f"{self.spec.coupling.name} on {self.spec.rig.name}, plan {self.spec.doe.name}: {n} tests, "
                f"{self.done} extracted, {len(self.failed)} failed, {self.pending} pending "
                f"({self.ran_tests} run now{' on ' + self.executor if self.executor else ''}, {self.wall_s:.1f} s; "
                f"record {self.spec.duration_s:g} s after the impact)")

    def to_frame(self) -> pd.DataFrame:
        """The results table: one row per finished test (plan fields, extracted values, flags)."""
        return self.results.copy()

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready figures of the run (the results table is :meth:`to_frame`)."""
        return {"folder": str(self.root), "rig": self.spec.rig.name, "coupling": self.spec.coupling.name,
                "doe": self.spec.doe.name, "tests": len(self.spec.tests), "extracted": self.done,
                "failed": [{"test_id": int(t), "error": e} for t, e in self.failed], "errors": list(self.errors),
                "pending": self.pending, "ran_tests": self.ran_tests, "executor": self.executor,
                "wall_s": self.wall_s, "duration_s": self.spec.duration_s, "warnings": list(self.warnings)}

    def __repr__(self) -> str:
        return f"<CampaignRun {self.root}: {self.summary()}>"

    def _repr_html_(self) -> str:
        return f"<p>{self.summary()}</p>" + self.results.head(10).to_html(index=False)


def run_campaign(out: str | Path, rig: str | Path | None = None, coupling: str | Path | None = None,
                 doe: str | Path | None = None, *, workers: int | None = None, scheduler: str | None = None,
                 resume: bool = False, duration_s: float | None = None, chunk_size: int | None = None,
                 log_format: str | None = None, window: str | None = None, progress: bool = True,
                 max_chunks: int | None = None, scheduler_timeout_s: float = SCHEDULER_TIMEOUT_S) -> CampaignRun:
    """Simulate, log and extract every test of the plan ``doe`` on ``rig`` with ``coupling``
    (files or shipped preset names; None: the shipped defaults, or with ``resume`` the
    campaign's own, restored from its manifest) into the folder ``out``.

    workers: local processes (None: every local core; 1: this process); scheduler: a Dask
    scheduler address instead; resume: continue the campaign in ``out`` (same rig, coupling,
    plan and settings, else a one-line error and nothing touched); duration_s: record length
    after the impact (None: twice the longest predicted period, see :func:`prepare`);
    chunk_size: tests per batched simulation (None: :data:`~droptower.campaign.spec.CHUNK_SIZE`);
    log_format: ``parquet`` (None; compact logs) or ``csv``; window: the extractor's fit window
    (None: ``first-cycle``). With ``resume``, a setting left None is the folder's. progress: a
    tqdm bar on stderr; max_chunks: stop after this many chunks (an interrupted campaign, for
    tests and trial runs).
    """
    t_start = time.perf_counter()
    if workers is not None and workers < 1:
        raise DroptowerError(f"must be at least 1, got {workers}", where="workers")
    spec = _spec(out, rig, coupling, doe, resume, {"duration_s": duration_s, "chunk_size": chunk_size,
                                                   "log_format": log_format, "window": window})
    layout = layout_for(out, spec)
    # a Dask scheduler is asked first: if it does not answer, the folder is not touched
    cluster = make_executor(workers, scheduler, scheduler_timeout_s) if scheduler is not None else None
    try:
        with folder_lock(layout.root):
            return _run(spec, layout, resume, workers, cluster, progress, max_chunks, t_start)
    except WriteError as exc:
        raise WriteError(f"{exc.problem}; the finished tests are kept: make room, then continue with `resume`",
                         file=exc.file) from None
    finally:
        if cluster is not None:
            cluster.close()


def _spec(out: str | Path, rig: str | Path | None, coupling: str | Path | None, doe: str | Path | None, resume: bool,
          given: dict[str, Any]) -> CampaignSpec:
    """The campaign's spec: the given inputs and settings, with ``resume`` the folder's where not given."""
    saved = saved_settings(Path(out)) if resume else {}
    inputs = {"rig": rig, "coupling": coupling, "doe": doe}
    if resume and None in inputs.values():
        inputs = {k: v for k, v in inputs.items() if v is not None} | {
            k: v for k, v in saved_inputs(Path(out)).items() if inputs[k] is None}
    defaults = {"rig": DEFAULT_RIG, "coupling": DEFAULT_COUPLING, "doe": DEFAULT_DOE}
    return prepare(**{k: inputs.get(k) or v for k, v in defaults.items()},
                   **{k: saved.get(k) if v is None else v for k, v in given.items()})


def estimate_campaign(out: str | Path, rig: str | Path | None = None, coupling: str | Path | None = None,
                      doe: str | Path | None = None, *, workers: int | None = None, scheduler: str | None = None,
                      resume: bool = False, duration_s: float | None = None, chunk_size: int | None = None,
                      log_format: str | None = None, window: str | None = None,
                      scheduler_timeout_s: float = SCHEDULER_TIMEOUT_S) -> Estimate:
    """Time and disk the campaign :func:`run_campaign` would run with the same arguments
    (:mod:`.estimate`); ``out`` is only read (with ``resume``: its settings and finished tests)."""
    out = Path(out)  # a path even where only a resume reads it (a TypeError for anything else)
    if workers is not None and workers < 1:
        raise DroptowerError(f"must be at least 1, got {workers}", where="workers")
    spec = _spec(out, rig, coupling, doe, resume, {"duration_s": duration_s, "chunk_size": chunk_size,
                                                   "log_format": log_format, "window": window})
    to_run = len(spec.tests) - (len(finished(layout_for(out, spec), spec)) if resume else 0)
    cores = local_cores()
    if scheduler is not None:
        cluster = make_executor(workers, scheduler, scheduler_timeout_s)  # both given: a one-line error
        try:  # a cluster's workers may sit on other machines: each its own core
            workers = cores = max(1, len(cluster.client.scheduler_info(n_workers=-1).get("workers", {})))
        finally:
            cluster.close()
    return estimate(spec, cores if workers is None else workers, cores, to_run)


def _run(spec: CampaignSpec, layout: Layout, resume: bool, workers: int | None, cluster: DaskCluster | None,
         progress: bool, max_chunks: int | None, t_start: float) -> CampaignRun:
    from tqdm import tqdm

    old, warnings = open_folder(layout, spec, resume)
    created = old.get("created") if old else None
    status = {r["test_id"]: {k: r.get(k) for k in ("status", "error", "log_file")}
              for batch in finished_batches(layout, spec) for r in batch}
    write_manifest(layout, spec, status, created)

    plan = spec.tests[list(PLAN_COLUMNS)].to_dict(orient="records")
    tasks = []
    for index, rows in enumerate(spec.chunks()):
        todo = tuple(plan[i]["test_id"] not in status for i in rows)
        if any(todo):
            tasks.append(ChunkTask(index=index, layout=layout, plan=tuple(plan[i] for i in rows), todo=todo,
                                   rig=spec.rig, coupling=spec.coupling, duration_s=spec.duration_s,
                                   log_format=spec.log_format, window=spec.window))
    if max_chunks is not None:
        tasks = tasks[:max_chunks]
    if old is not None and progress:
        print(f"droptower: resuming {layout.root}: {len(status)} of {len(spec.tests)} tests finished, "
              f"{sum(sum(t.todo) for t in tasks)} to run", file=sys.stderr)

    run = CampaignRun(spec=spec, root=layout.root, executor="", results=pd.DataFrame(), failed=[], errors=[],
                      pending=0, ran_tests=0, wall_s=0.0, warnings=warnings)
    if tasks:
        if cluster is None:
            workers = min(local_cores() if workers is None else workers, len(tasks))
        with cluster or make_executor(workers) as executor:
            run.executor = executor.description
            bar = tqdm(total=len(spec.tests), initial=len(status), unit="test", desc="campaign", file=sys.stderr,
                       disable=None if progress else True)
            stopped = False
            warm = None
            next_manifest = time.monotonic() + MANIFEST_EVERY_S
            try:
                for task, outcome in executor.run(run_chunk, tasks):
                    if warm is None and not isinstance(executor, InProcess):  # the workers are forked by now
                        warm = _warm_summary(spec)
                    if isinstance(outcome, ChunkOutcome):
                        status.update(outcome.status)
                        run.ran_tests += len(outcome.status)
                        run.simulate_cpu_s += outcome.simulate_cpu_s
                        run.write_cpu_s += outcome.write_cpu_s
                        run.extract_cpu_s += outcome.extract_cpu_s
                        run.peak_rss_worker_mb = max(run.peak_rss_worker_mb, outcome.peak_rss_mb)
                        bar.update(len(outcome.status))
                    elif isinstance(outcome, (WriteError, OSError)):  # the folder cannot take more: stop
                        stopped = True
                        raise outcome if isinstance(outcome, WriteError) else WriteError.from_os_error(outcome)
                    else:
                        ids = [r["test_id"] for r in task.plan]
                        run.errors.append(f"chunk {task.index} (tests {ids[0]}-{ids[-1]}): internal error "
                                          f"({type(outcome).__name__}: {outcome})")  # listed once, at the end
                    if time.monotonic() >= next_manifest:
                        t_manifest = time.monotonic()
                        write_manifest(layout, spec, status, created)
                        # a large plan's manifest takes long to write: keep it a small share of the run
                        next_manifest = time.monotonic() + max(MANIFEST_EVERY_S,
                                                               20.0 * (time.monotonic() - t_manifest))
            finally:
                bar.close()
                if warm is not None:  # no thread outlives the run (a later pool forks this process)
                    warm.join()
                try:
                    write_manifest(layout, spec, status, created)
                except WriteError:
                    if not stopped:  # else the error in flight says it already
                        raise

    run.results = assemble_batches(finished_batches(layout, spec))
    write_results(run.results, layout.results_parquet, layout.results_csv)
    run.outputs = [(layout.results_parquet, f"{len(run.results)} test(s), one row each"),
                   (layout.results_csv, f"{len(run.results)} test(s), one row each"),
                   (layout.logs, "a log per simulated test")]
    if run.done:
        run.outputs += write_condition_summary(run)
    failed = run.results[run.results["status"] == "failed"]
    run.failed = [(int(i), str(e or "")) for i, e in zip(failed["test_id"], failed["error"])]
    run.pending = len(spec.tests) - len(run.results)
    run.peak_rss_main_mb = peak_rss_mb()
    run.peak_rss_worker_mb = max(run.peak_rss_worker_mb, peak_rss_mb(resource.RUSAGE_CHILDREN))
    run.wall_s = time.perf_counter() - t_start
    return run


def _warm_summary(spec: CampaignSpec) -> threading.Thread:
    """Import what :func:`write_condition_summary` needs (the maps package; matplotlib where the plan
    varies the preload, for Fig. 11) on a thread while the workers run the chunks: this process
    only waits for them then, so the imports (~0.5 s of CPU) leave the time after the last chunk.
    Started only once the pool has forked its workers (a fork while a thread imports would leave
    the child holding the import locks)."""

    def load() -> None:
        try:
            import droptower.io.tables  # noqa: F401
            import droptower.maps.summary  # noqa: F401

            if spec.tests["preload_nm"].nunique() > 1:
                import matplotlib.backends.backend_agg  # noqa: F401
                import matplotlib.pyplot  # noqa: F401
        except Exception:  # noqa: BLE001  an import that fails here fails again, and is reported, where it is used
            pass

    thread = threading.Thread(target=load, name="droptower-warm-summary", daemon=True)
    thread.start()
    return thread


def write_condition_summary(run: CampaignRun) -> list[tuple[Path, str]]:
    """``summary.csv`` in the campaign folder (per condition: mean and std over repeats), and
    Rapp et al. 2022, Fig. 11 when the plan varies the preload. Returns (path, what) of each."""
    from droptower.io.tables import write_table
    from droptower.maps.summary import FIG11, condition_summary, plot_preload_effect

    summary = condition_summary(run.results)
    written = [(write_table(summary, run.root / "summary.csv"), f"{len(summary)} condition(s), mean and std over repeats")]
    if summary["preload_nm"].nunique() > 1:
        title = f"{run.spec.coupling.name} on {run.spec.rig.name}, plan {run.spec.doe.name}"
        written.append((plot_preload_effect(summary, run.root / FIG11, title), "preload effect (Rapp et al. 2022, Fig. 11)"))
    return written
