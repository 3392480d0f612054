"""What a stored study came from, and whether it is still what the checkout computes.

A stored study is keyed by what its figures depend on: its inputs (the rig, coupling and
test-plan presets and the paper's Table 4, by SHA-256) and a fingerprint of the code, the exact
figures of the reduced study (:func:`figures`), which the test suite runs anyway. The stored
study is current when the inputs hash the same and the reduced study computed now reproduces
the stored fingerprint to :data:`FINGERPRINT_RTOL` (:func:`figure_differences`): an edit that
changes no figure (a comment, a rename, a refactoring) leaves it current; one that moves a
figure, or a changed preset, makes it stale.

The hashes of the source files (the study script and every Python file of the package but
``cli/``, ``__main__.py`` and ``report/``, which only present results) are still stored: they are
not checked, they say which files changed since a stale study was computed.
"""
from __future__ import annotations

import hashlib
import math
import platform
from importlib import metadata
from pathlib import Path
from typing import Any

import droptower
from droptower.configs import resolve
from droptower.data import table4_path

#: the one command that recomputes the stored study, the benchmarks' figures and the README's blocks
REGENERATE = "python analysis/readme_figures.py"
PACKAGE = Path(droptower.__file__).resolve().parent
STUDY_SCRIPT = Path(__file__).resolve().parent / "run_study.py"
#: the fingerprint's tolerance: a reduced study's figure reproduces the stored one within this
#: relative difference (the same machine gives them bit for bit; another CPU's libm or BLAS moves
#: the last digits, ~1e-15, which a fit can amplify but not to 1e-9)
FINGERPRINT_RTOL = 1e-9
#: ... and within this absolute difference, for figures that are zero
FINGERPRINT_ATOL = 1e-12
#: keys of a study summary that are not figures of the study: timings of the machine that ran it,
#: where it came from
NOT_FIGURES = ("provenance", "campaign_wall_s", "study_wall_s", "campaign_hashes")
#: measured speeds, at any depth: a key, or a target (``{"target": ..., "value": ...}``) named so
TIMED = ("real_time_factor", "real-time factor")
#: the stored fingerprint, beside the full study's summary
FINGERPRINT_FILE = "reduced_study.json"
#: folders and files of the package that cannot change a stored figure (presentation only)
NOT_HASHED = ("cli", "report", "__main__.py")


def file_sha256(path: Path) -> str:
    """SHA-256 of a text file's content with line ends normalised (a checkout's CRLF is the same file)."""
    return hashlib.sha256(path.read_bytes().replace(b"\r\n", b"\n")).hexdigest()


def source_files() -> dict[str, Path]:
    """The Python files a stored figure can depend on, by a machine-independent name: the study
    script and the package's modules (``droptower/...``), sorted."""
    files = {f"analysis/{STUDY_SCRIPT.name}": STUDY_SCRIPT}
    files.update((p.relative_to(PACKAGE.parent).as_posix(), p) for p in sorted(PACKAGE.rglob("*.py"))
                 if p.relative_to(PACKAGE).parts[0] not in NOT_HASHED and "__pycache__" not in p.parts)
    return files


def input_files(rig: str, coupling: str, doe: str) -> dict[str, Path]:
    """The study's inputs by a machine-independent name: its presets and the paper's Table 4."""
    return {f"rig {Path(rig).stem}": resolve(rig, "rigs"), f"coupling {Path(coupling).stem}": resolve(coupling, "couplings"),
            f"doe {Path(doe).stem}": resolve(doe, "doe"), "table4 rapp2022_table4_map.csv": table4_path()}


def provenance(rig: str, coupling: str, doe: str) -> dict[str, Any]:
    """The hashes a stored study is checked against, and (informative, not checked) the versions it ran with."""
    files = {name: file_sha256(path) for name, path in source_files().items()}
    return {
        "regenerate": REGENERATE,
        "inputs_sha256": {name: file_sha256(path) for name, path in input_files(rig, coupling, doe).items()},
        "source_sha256": hashlib.sha256("".join(f"{k} {v}\n" for k, v in files.items()).encode()).hexdigest(),
        "source_files_sha256": files,
        "versions": {"python": platform.python_version(),
                     **{name: metadata.version(name) for name in ("numpy", "scipy", "numba", "pymunk", "pandas")}},
    }


def stale_reasons(stored: dict[str, Any], current: dict[str, Any]) -> list[str]:
    """Every difference between a stored provenance and the current one, inputs and source files
    (informative: which files changed since a study was computed; :func:`input_reasons` and the
    fingerprint decide whether it is current)."""
    reasons = input_reasons(stored, current)
    old, new = stored["source_files_sha256"], current["source_files_sha256"]
    reasons += [f"{f} changed" for f in sorted(set(old) & set(new)) if old[f] != new[f]]
    reasons += [f"{f} added" for f in sorted(set(new) - set(old))]
    reasons += [f"{f} removed" for f in sorted(set(old) - set(new))]
    return reasons


def figures(summary: dict[str, Any]) -> dict[str, float]:
    """Every number of a study's summary by its path (``map_fit.stiffness_rms_error_pct``,
    ``map_range.hull_amplitude_deg_frequency_hz.3.1``), timings, measured speeds and provenance
    left out (:data:`NOT_FIGURES`, :data:`TIMED`); booleans and integers as floats, strings skipped."""
    out: dict[str, float] = {}

    def walk(value: Any, path: str) -> None:
        if isinstance(value, dict):
            if str(value.get("target", "")).startswith(TIMED):
                return
            for key, item in value.items():
                if (not path and key in NOT_FIGURES) or key in TIMED:
                    continue
                walk(item, f"{path}.{key}" if path else str(key))
        elif isinstance(value, (list, tuple)):
            for i, item in enumerate(value):
                walk(item, f"{path}.{i}")
        elif isinstance(value, (bool, int, float)) or value is None:
            out[path] = float("nan") if value is None else float(value)

    walk(summary, "")
    return out


def figure_differences(stored: dict[str, float], current: dict[str, float], rtol: float = FINGERPRINT_RTOL,
                       atol: float = FINGERPRINT_ATOL) -> list[str]:
    """The figures in which ``current`` does not reproduce ``stored`` ([] when it does): a value
    off by more than ``rtol`` (relative) and ``atol`` (absolute), a figure missing or added. NaN
    reproduces NaN."""
    def same(a: float, b: float) -> bool:
        return (math.isnan(a) and math.isnan(b)) or abs(a - b) <= max(atol, rtol * max(abs(a), abs(b)))

    reasons = [f"{k}: stored {stored[k]!r}, now {current[k]!r}" for k in stored if k in current
               and not same(stored[k], current[k])]
    reasons += [f"{k}: no longer computed" for k in stored if k not in current]
    reasons += [f"{k}: not in the stored fingerprint" for k in current if k not in stored]
    return reasons


def input_reasons(stored: dict[str, Any], current: dict[str, Any]) -> list[str]:
    """The inputs (presets, Table 4) in which two provenances differ ([] when the same)."""
    old, new = stored["inputs_sha256"], current["inputs_sha256"]
    reasons = [f"{name} changed" for name in new if name in old and old[name] != new[name]]
    reasons += [f"{name} is not among the stored study's inputs" for name in new if name not in old]
    reasons += [f"the stored study ran {name}" for name in old if name not in new]
    return reasons
