"""What a campaign is: rig, coupling, test plan and run settings, resolved, checked and hashed.

The identity of a campaign is the content of its three input files (parsed TOML, so comments
and layout do not count), the expanded plan (every test with its seed) and the settings that
change results (record length, chunk size, log format, fit window). Two runs with the same
identity produce the same files, bit for bit, so a folder can be resumed by any later run with
the same identity and by no other.

The chunk size is part of the identity: tests are simulated in fixed chunks of the plan (one
batched :func:`droptower.rig.simulate.simulate` call each), whatever the number of workers,
because a batch's shared steps (the preload solve, pymunk's coordinates) may differ in the last
bits with the batch's make-up.
"""
from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from droptower.configs import DEFAULT_COUPLING, DEFAULT_DOE, DEFAULT_RIG, read_toml, resolve
from droptower.errors import DroptowerError

#: Tests per chunk: one batched pymunk space each. CPU of the simulation per test on the Table-2
#: plan: ~45 ms alone, 12.9 ms at 25, 10.1 at 50, 8.8 at 100, 9.0 at 200 (the per-step Python cost
#: is shared by the batch); 75 also splits the 450-test plan into 6 equal chunks (3 per worker of 2).
CHUNK_SIZE = 75
LOG_FORMATS = ("parquet", "csv")
#: Plan columns, in the order the results table starts with.
PLAN_COLUMNS = ("test_id", "case", "inertia_kgm2", "drop_mass_kg", "drop_height_m", "preload_nm", "repeat", "seed")


def sha256_of(value: Any) -> str:
    """SHA-256 of the canonical JSON text of ``value`` (sorted keys, no spaces)."""
    text = json.dumps(value, sort_keys=True, separators=(",", ":"), default=str, allow_nan=True)
    return hashlib.sha256(text.encode()).hexdigest()


@dataclass
class CampaignSpec:
    """A resolved campaign: loaded rig, coupling and plan, the test table and the settings.

    tests: one row per test (:data:`PLAN_COLUMNS`); duration_s: record length after the
    impact (s); chunk_size: tests per batched simulation; log_format: ``parquet`` or ``csv``;
    window: the extractor's fit window; inputs: per input (``rig``, ``coupling``, ``doe``) its
    file and parsed content.
    """

    rig: Any                # droptower.rig.config.RigConfig
    coupling: Any           # droptower.rheology.Coupling
    doe: Any                # droptower.rig.config.DOE
    tests: pd.DataFrame
    duration_s: float
    chunk_size: int
    log_format: str
    window: str
    inputs: dict[str, dict[str, Any]] = field(default_factory=dict)
    _hashes: tuple[str, dict[str, str]] | None = field(default=None, init=False, repr=False, compare=False)

    @property
    def settings(self) -> dict[str, Any]:
        return {"duration_s": self.duration_s, "chunk_size": self.chunk_size, "log_format": self.log_format,
                "window": self.window}

    @property
    def plan_records(self) -> list[dict[str, Any]]:
        return self.tests[list(PLAN_COLUMNS)].to_dict(orient="records")

    def hashes(self) -> dict[str, str]:
        """SHA-256 per part of the identity: rig, coupling, doe, plan, settings (computed once:
        the plan's hash takes ~0.1 s per thousand tests)."""
        key = sha256_of([self.inputs, self.settings, len(self.tests)])
        if self._hashes is None or self._hashes[0] != key:
            self._hashes = (key, self._compute_hashes())
        return dict(self._hashes[1])

    def _compute_hashes(self) -> dict[str, str]:
        return {"rig": sha256_of(self.inputs["rig"]["content"]),
                "coupling": sha256_of(self.inputs["coupling"]["content"]),
                "doe": sha256_of(self.inputs["doe"]["content"]),
                "plan": sha256_of(self.plan_records),
                "settings": sha256_of(self.settings)}

    def chunks(self) -> list[np.ndarray]:
        """Test indices of each chunk: consecutive runs of ``chunk_size`` tests of the plan."""
        n = len(self.tests)
        return [np.arange(lo, min(lo + self.chunk_size, n)) for lo in range(0, n, self.chunk_size)]


def _record_length(rig: Any, coupling: Any, doe: Any, window: Any) -> float:
    """The record the planner's periods ask for (:func:`droptower.rig.predictions.record_length_s`)."""
    from droptower.rig.predictions import plan, record_length_s

    return record_length_s(plan(rig, coupling, doe.conditions())["first_period_s"], window.length_s)


def prepare(rig: str | Path = DEFAULT_RIG, coupling: str | Path = DEFAULT_COUPLING, doe: str | Path = DEFAULT_DOE,
            *, duration_s: float | None = None, chunk_size: int | None = None, log_format: str | None = None,
            window: str | None = None) -> CampaignSpec:
    """Load and check the inputs (files or shipped preset names) and fix the settings.

    duration_s: record length after the impact (s); None: twice the longest first period the planner
    predicts (:func:`droptower.rig.predictions.record_length_s`). chunk_size (default :data:`CHUNK_SIZE`), log_format (``parquet``)
    and window (``first-cycle``, the extractor's fit window). Every problem is a one-line
    :class:`DroptowerError`.
    """
    from droptower.extract.window import Window
    from droptower.rheology import load_coupling
    from droptower.rig.config import load_doe, load_rig
    from droptower.rig.simulate import check_size

    chunk_size = CHUNK_SIZE if chunk_size is None else chunk_size
    log_format = "parquet" if log_format is None else log_format
    window = "first-cycle" if window is None else window
    if log_format not in LOG_FORMATS:
        raise DroptowerError(f"unknown log format {log_format!r} (use {' or '.join(LOG_FORMATS)})",
                             where="log format")
    if int(chunk_size) != chunk_size or chunk_size < 1:
        raise DroptowerError(f"chunk size must be a positive integer, got {chunk_size}", where="chunk size")
    if duration_s is not None and not (math.isfinite(duration_s) and duration_s > 0):
        raise DroptowerError(f"record duration must be positive, got {duration_s} s", where="duration")
    fit_window = Window.parse(window)
    paths = {"rig": resolve(rig, "rigs"), "coupling": resolve(coupling, "couplings"), "doe": resolve(doe, "doe")}
    rig_cfg, model, plan = load_rig(paths["rig"]), load_coupling(paths["coupling"]), load_doe(paths["doe"])
    if model.n_sets != 1:
        raise DroptowerError(f"a campaign runs one coupling parameter set, this file has {model.n_sets}",
                             file=paths["coupling"])
    plan.check(rig_cfg)
    tests = plan.tests()
    if duration_s is None:
        duration_s = _record_length(rig_cfg, model, plan, fit_window)
    check_size(rig_cfg, model, min(int(chunk_size), len(tests)), float(duration_s), where="duration_s")
    inputs = {kind: {"file": str(path), "content": read_toml(path)} for kind, path in paths.items()}
    return CampaignSpec(rig=rig_cfg, coupling=model, doe=plan, tests=tests, duration_s=float(duration_s),
                        chunk_size=int(chunk_size), log_format=log_format, window=str(fit_window),
                        inputs=inputs)
