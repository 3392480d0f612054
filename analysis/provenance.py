"""What a stored study came from: SHA-256 hashes of the presets it ran and of the package's
source files, so a test can tell a stale stored result from a current one.

A stored result is stale when any hashed file has changed since it was computed. The source
files hashed are the study script (``analysis/run_study.py``) and every Python file of the
package except the command-line layer (``cli/``, ``__main__.py``) and the HTML report
(``report/``): those only present results and write nothing the study stores. Hashing the rest
(identification included: the lever's free decay may be shared with the rig) errs on the side
of calling a result stale.
"""
from __future__ import annotations

import hashlib
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
    """What differs between a stored provenance and the current one ([] when the stored result is current)."""
    old, new = stored["inputs_sha256"], current["inputs_sha256"]
    reasons = [f"{name} changed" for name in new if name in old and old[name] != new[name]]
    reasons += [f"{name} is not among the stored study's inputs" for name in new if name not in old]
    reasons += [f"the stored study ran {name}" for name in old if name not in new]
    old, new = stored["source_files_sha256"], current["source_files_sha256"]
    reasons += [f"{f} changed" for f in sorted(set(old) & set(new)) if old[f] != new[f]]
    reasons += [f"{f} added" for f in sorted(set(new) - set(old))]
    reasons += [f"{f} removed" for f in sorted(set(old) - set(new))]
    return reasons
