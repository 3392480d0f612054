"""The decay figure of every test of a report, drawn in parallel processes.

A campaign's results table stores every test's decay fit (Rapp et al. 2022, eq. 13 and 17:
amplitude, decay coefficient, angular frequency and phase of the angle; amplitude, phase and
offset of the torque; the impact time, the window and the pre-trigger offsets): its figure
needs the measured trace from the log and those numbers, not the fit again. A test whose row
lacks them (a failed test, an extraction's results table, which may name channel roles or hold
several drops per log) is extracted again from its log, as the extraction did. Tests go to
worker processes :data:`TESTS_PER_TASK` at a time (:func:`droptower.campaign.executors.make_executor`):
a report of 4 500 tests reads 4 500 logs; :class:`Drawing` does it while the report's own
process fits the map and writes the tables.
"""
from __future__ import annotations

import html
import math
import sys
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from droptower.damped_cosine import DecayFit, TorqueFit
from droptower.errors import DroptowerError
from droptower.extract.result import DEG
from droptower.maps.results import flag_list
from droptower.report.figures import StoredFit, decay_figure
from droptower.report.run import Run

#: Tests per task of a worker process: enough that a task costs far more than sending it.
TESTS_PER_TASK = 50
#: Results-table columns of the stored angle fit and of what the figure's title shows.
ANGLE_COLUMNS = ("impact_onset_time_s", "window_start_s", "window_end_s", "angle_offset_deg",
                 "initial_amplitude_deg", "decay_coefficient_per_s", "angular_frequency_rad_per_s", "phase_rad",
                 "frequency_hz", "amplitude_deg", "stiffness_nm_per_deg", "damping_ratio")
#: Results-table columns of the stored torque fit (all NaN for a log without torque).
TORQUE_COLUMNS = ("torque_offset_nm", "torque_amplitude_nm", "torque_phase_rad", "torque_fit_offset_nm")


def stored_fit(row: dict[str, Any]) -> StoredFit | None:
    """The decay fit a results-table row stores (the columns :data:`ANGLE_COLUMNS` and
    :data:`TORQUE_COLUMNS`, units in their names), or None where a value of the angle fit is
    missing or not finite. The torque fit is (a, b, offset) = (T̂ cos Φ_T, T̂ sin Φ_T, offset),
    the inverse of its amplitude hypot(a, b) and phase atan2(b, a) (docs/theory.md#extraction)."""
    try:
        v = {k: float(row[k]) for k in ANGLE_COLUMNS}
    except (KeyError, TypeError, ValueError):
        return None
    if not all(math.isfinite(x) for x in v.values()):
        return None
    delta, omega = v["decay_coefficient_per_s"], v["angular_frequency_rad_per_s"]
    angle = DecayFit(np.array([v["initial_amplitude_deg"] * DEG, delta, omega, v["phase_rad"]]), np.full((4, 4), np.nan),
                     math.nan)
    torque = None
    t = {k: _number(row.get(k)) for k in TORQUE_COLUMNS}
    if all(math.isfinite(x) for x in t.values()):
        a = t["torque_amplitude_nm"] * math.cos(t["torque_phase_rad"])
        b = t["torque_amplitude_nm"] * math.sin(t["torque_phase_rad"])
        torque = TorqueFit(np.array([a, b, t["torque_fit_offset_nm"]]), np.full((3, 3), np.nan), math.nan, delta, omega)
    return StoredFit(impact_time_s=v["impact_onset_time_s"], window_start_s=v["window_start_s"],
                     window_end_s=v["window_end_s"], angle_offset_rad=v["angle_offset_deg"] * DEG, angle_fit=angle,
                     torque_offset_nm=t["torque_offset_nm"] if torque is not None else math.nan, torque_fit=torque)


def _number(value: Any) -> float:
    try:
        return float(value)
    except (TypeError, ValueError):
        return math.nan


def title(frequency_hz: float, amplitude_deg: float, stiffness_nm_per_deg: float, damping_ratio: float,
          flags: list[str] | tuple[str, ...]) -> str:
    """The figure's title: the values the results table reports for the test (HTML-escaped)."""
    return html.escape(f"f = {frequency_hz:.2f} Hz, amplitude = {amplitude_deg:.3f} deg, "
                       f"c = {stiffness_nm_per_deg:.1f} N·m/deg, d = {damping_ratio:.3f}"
                       + (f" [{', '.join(flags)}]" if flags else ""))


@dataclass(frozen=True)
class Job:
    """One test's figure to draw: its name, log (None: not found), drop number in the log, the
    inertia to extract with (kg·m², None: the log's), and the row's stored fit with its title
    values (None: extract the log again)."""

    name: str
    log: Path | None
    drop_index: int
    inertia_kgm2: float | None
    stored: dict[str, Any] | None
    error: str | None = None


def jobs(run: Run) -> list[Job]:
    """The figures a run's report draws: one job per test. A campaign's rows, and a lab folder's
    extracted here, carry their stored fits (extracted with the run's settings); a lab folder's
    row whose extraction failed carries its error (not extracted a second time)."""
    table = run.table
    n = len(table)
    inertia = pd.to_numeric(table.get("inertia_kgm2", pd.Series(np.nan, index=table.index)), errors="coerce")
    drop_index = pd.to_numeric(table.get("drop_index", pd.Series(1, index=table.index)), errors="coerce")
    wanted = [c for c in (*ANGLE_COLUMNS, *TORQUE_COLUMNS, "flags") if c in table.columns]
    rows = table[wanted].to_dict(orient="records") if run.kind in ("campaign", "log folder") else [None] * n
    errors = [None] * n
    if run.kind == "log folder" and "error" in table.columns:
        errors = [e if isinstance(e, str) and e else None for e in table["error"]]
    out = []
    for i, (name, log) in enumerate(zip(run.test, run.logs)):
        j, k = float(inertia.iloc[i]), float(drop_index.iloc[i])
        row = rows[i]
        if row is not None and not (stored_fit(row) is not None and "flags" in row):
            row = None
        out.append(Job(name, log, int(k) if math.isfinite(k) and k >= 1 else 1,
                       j if math.isfinite(j) and j > 0 else None, row, errors[i]))
    return out


def draw(task: tuple[list[Job], dict[str, Any]]) -> list[tuple[str, object]]:
    """A worker's task: (jobs, keyword arguments of :class:`droptower.extract.files.Settings`)
    -> per job its name and figure, or why there is none (a one-line text)."""
    from droptower.extract.files import Settings, extract_file

    batch, settings_kw = task
    base = Settings(**settings_kw)
    out: list[tuple[str, object]] = []
    for job in batch:
        if job.log is None:
            out.append((job.name, "log not found"))
            continue
        if job.error is not None:
            out.append((job.name, f"extraction failed: {job.error}"))
            continue
        fit = stored_fit(job.stored) if job.stored is not None else None
        try:
            if fit is not None:
                signals = base.read_signals(job.log, sample_rate_hz=base.sample_rate_hz,
                                            reader_options=base.reader_options)
                r = job.stored
                text = title(r["frequency_hz"], r["amplitude_deg"], r["stiffness_nm_per_deg"], r["damping_ratio"],
                             flag_list(r["flags"]))
            else:
                settings = base if job.inertia_kgm2 is None else Settings(**settings_kw, inertia_kgm2=job.inertia_kgm2)
                signals, result = extract_file(job.log, settings, job.drop_index)
                fit = result
                text = title(result.frequency_hz, result.amplitude_ref_rad / DEG, result.stiffness_nm_per_rad * DEG,
                             result.damping_ratio, result.flags)
        except DroptowerError as exc:
            doing = "read" if fit is not None else "extracted again"
            out.append((job.name, f"the log cannot be {doing}: {exc.message.replace(str(job.log), job.log.name)}"))
            continue
        out.append((job.name, decay_figure(signals, fit, text)))
    return out


class Drawing:
    """The decay figures of a run drawn in the background (worker processes, collected by a
    thread of this process) while this process does the rest of the report:

        with Drawing(run, channels) as drawing:
            ...  # the map, the tables
            figures = drawing.result()

    channels: role -> ``NAME[:UNIT]`` for reading the logs; progress: a progress bar on stderr;
    workers: processes drawing (None: every local core; 1: this process, in the thread)."""

    def __init__(self, run: Run, channels: dict[str, str], progress: bool = False, workers: int | None = None):
        from droptower.campaign.executors import local_cores
        from droptower.extract.window import Window

        settings_kw = dict(run.extract)
        settings_kw["window"] = Window.parse(settings_kw.pop("window", "first-cycle"))
        settings_kw["roles"] = channels
        self.jobs = jobs(run)
        self.tasks = [(self.jobs[k:k + TESTS_PER_TASK], settings_kw) for k in range(0, len(self.jobs), TESTS_PER_TASK)]
        if workers is not None and workers < 1:
            raise DroptowerError(f"must be at least 1, got {workers}", where="workers")
        self.workers = max(1, min(local_cores() if workers is None else workers, len(self.tasks)))
        self.progress = progress
        self._drawn: dict[str, object] = {}
        self._error: BaseException | None = None
        self._stop = threading.Event()

    def __enter__(self) -> "Drawing":
        from droptower.campaign.executors import make_executor

        self._executor = make_executor(self.workers).__enter__()
        self._executor.start()  # its processes exist before this process runs a second thread
        self._thread = threading.Thread(target=self._collect, name="report-decays", daemon=True)
        self._thread.start()
        return self

    def _collect(self) -> None:
        from tqdm import tqdm

        try:
            with tqdm(total=len(self.jobs), desc="report", unit="test", file=sys.stderr,
                      disable=None if self.progress else True) as bar:  # None: a bar on a terminal only
                for task, outcome in self._executor.run(draw, self.tasks):
                    if self._stop.is_set():  # the report failed: no more tasks
                        return
                    if isinstance(outcome, BaseException):
                        raise outcome
                    self._drawn.update(outcome)
                    bar.update(len(task[0]))
        except BaseException as exc:  # given to the caller by result()
            self._error = exc

    def result(self) -> dict[str, object]:
        """Per test name (in the run's order): its figure, or why there is none (a one-line text)."""
        self._thread.join()
        if self._error is not None:
            raise self._error
        return {job.name: self._drawn[job.name] for job in self.jobs}

    def __exit__(self, exc_type: Any, *exc: Any) -> None:
        if exc_type is not None:
            self._stop.set()
        self._thread.join()
        self._executor.__exit__(exc_type, *exc)


def decay_figures(run: Run, channels: dict[str, str], progress: bool = False,
                  workers: int | None = None) -> dict[str, object]:
    """Per test name (in the run's order): its decay-fit figure, or why there is none (a
    one-line text). workers: processes drawing them (None: every local core; 1: this process)."""
    with Drawing(run, channels, progress, workers) as drawing:
        return drawing.result()
