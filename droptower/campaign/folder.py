"""The campaign folder on disk: layout, manifest and per-test records.

::

    DIR/manifest.json            identity (hashes and contents of rig, coupling, plan), settings,
                                 versions, per-test status (done / failed / pending)
    DIR/logs/test_00042.parquet  the simulated log of test 42 (the project's log format)
    DIR/records/test_00042.json  its result record: plan fields, extracted values, status
    DIR/results.parquet, .csv    one row per finished test, assembled from the records

A test is finished when its record exists; the record is written (atomically: a temporary
file, then :func:`os.replace`) only after its log, so a record always has its log. A failed
extraction of a good log is a finished test too (status ``failed``, with the error): running it
again would fail the same way. Nothing in a folder that holds another campaign is ever
touched: the manifest's hashes decide.
"""
from __future__ import annotations

import contextlib
import fcntl
import functools
import json
import platform
from dataclasses import dataclass
from datetime import datetime, timezone
from importlib import metadata
from pathlib import Path
from typing import Any, Iterator

from droptower.campaign.spec import CampaignSpec
from droptower.errors import DroptowerError, WriteError
from droptower.io.droptower_log import atomic_write
from droptower.jsonsafe import json_safe

FORMAT = "droptower-campaign"
#: The lock file of a running campaign (see :func:`folder_lock`).
LOCK_NAME = ".droptower.lock"
FORMAT_VERSION = 1
#: Packages whose versions the manifest records (results may change with any of them).
PACKAGES = ("droptower", "numpy", "scipy", "pymunk", "numba", "pandas", "pyarrow")


@dataclass(frozen=True)
class Layout:
    """Paths inside a campaign folder; test files are numbered with ``width`` digits."""

    root: Path
    width: int = 5

    @property
    def manifest(self) -> Path:
        return self.root / "manifest.json"

    @property
    def records(self) -> Path:
        return self.root / "records"

    @property
    def logs(self) -> Path:
        return self.root / "logs"

    @property
    def results_parquet(self) -> Path:
        return self.root / "results.parquet"

    @property
    def results_csv(self) -> Path:
        return self.root / "results.csv"

    def log_file(self, test_id: int, log_format: str) -> str:
        """The log of a test, relative to the folder (as the results table lists it)."""
        return f"logs/test_{test_id:0{self.width}d}.{log_format}"

    def record(self, test_id: int) -> Path:
        return self.records / f"test_{test_id:0{self.width}d}.json"


def layout_for(root: str | Path, spec: CampaignSpec) -> Layout:
    return Layout(Path(root), max(5, len(str(len(spec.tests) - 1))))


@functools.cache
def versions() -> dict[str, str]:
    out = {"python": platform.python_version()}
    for name in PACKAGES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = "not installed"
    return out


def write_json(path: Path, value: Any, indent: int | None = 1) -> Path:
    """Write strict JSON (NaN and infinities as null, numpy scalars as numbers) atomically;
    ``indent=None``: one line (Python's C encoder, several times faster than an indented one)."""
    text = json.dumps(json_safe(value), indent=indent) + "\n"
    atomic_write(path, lambda tmp: Path(tmp).write_text(text))
    return path


def read_manifest(path: Path) -> dict[str, Any]:
    """A campaign folder's manifest; anything else is a one-line error (the folder is not touched)."""
    try:
        data = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError, RecursionError) as exc:
        raise DroptowerError(f"unreadable campaign manifest ({exc}); not touching this folder", file=path) from None
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise DroptowerError("not a droptower campaign manifest; not touching this folder", file=path)
    if data.get("format_version") != FORMAT_VERSION:
        raise DroptowerError(f"campaign manifest version {data.get('format_version')!r} is not supported "
                             f"(this droptower writes {FORMAT_VERSION})", file=path)
    return data


def saved_settings(root: Path) -> dict[str, Any]:
    """The settings of the campaign in ``root`` (empty if it holds none)."""
    manifest = Layout(root).manifest
    return dict(read_manifest(manifest).get("settings") or {}) if manifest.is_file() else {}


def saved_inputs(root: Path) -> dict[str, Path]:
    """Per input (``rig``, ``coupling``, ``doe``) of the campaign in ``root``, a TOML file holding
    exactly the content its manifest records: the original file if it still reads the same, else
    a copy written to ``root/inputs/`` (so a campaign resumes from its folder alone, whatever
    was moved or edited since). Empty if ``root`` holds no campaign."""
    import tomli_w

    from droptower.configs import read_toml

    manifest = Layout(root).manifest
    if not manifest.is_file():
        return {}
    out = {}
    for kind, entry in (read_manifest(manifest).get("inputs") or {}).items():
        original, content = Path(str(entry.get("file"))), entry.get("content")
        try:
            same = original.is_file() and read_toml(original) == content
        except DroptowerError:
            same = False
        if same:
            out[kind] = original
            continue
        copy = Layout(root).root / "inputs" / original.name
        try:
            copy.parent.mkdir(exist_ok=True)
            atomic_write(copy, lambda tmp: Path(tmp).write_text(tomli_w.dumps(content)))
        except (OSError, TypeError, ValueError) as exc:
            raise DroptowerError(f"cannot restore the campaign's {kind} from its manifest ({exc})", file=manifest) from None
        out[kind] = copy
    return out


def count_finished(layout: Layout) -> int:
    """Tests with a result record on disk (the manifest can lag behind after a kill)."""
    return sum(read_record(path) is not None for path in layout.records.glob("test_*.json"))


def _differences(old: dict[str, Any], spec: CampaignSpec) -> list[str]:
    """The parts of the identity in which the folder's campaign and ``spec`` differ, in words."""
    out = []
    for part, digest in spec.hashes().items():
        if old.get("hashes", {}).get(part) == digest:
            continue
        if part == "settings":
            was = old.get("settings") or {}
            out += [f"{key} ({was.get(key)!r} in the folder, {value!r} given)"
                    for key, value in spec.settings.items() if was.get(key) != value] or ["settings"]
        else:
            out.append(part)
    return out


def has_campaign(root: Path) -> bool:
    """True if ``root`` holds a campaign (its manifest)."""
    return Layout(Path(root)).manifest.is_file()


def check_folder(root: Path) -> None:
    """Refuse ``root`` if it is a file, or a non-empty folder without a campaign (a user's folder).

    The lock file and the empty ``logs/`` and ``records/`` of a start that could not write its
    manifest do not count."""
    root = Path(root)
    if root.exists() and not root.is_dir():
        raise DroptowerError("exists and is not a folder", file=root)
    if root.is_dir() and not has_campaign(root):
        layout = Layout(root)
        if any(p.name != LOCK_NAME and not (p in (layout.records, layout.logs) and not any(p.iterdir()))
               for p in root.iterdir()):
            raise DroptowerError("is not empty and holds no campaign (no manifest.json); choose an empty or new "
                                 "folder", file=root)


@contextlib.contextmanager
def folder_lock(root: Path) -> Iterator[None]:
    """Hold an OS-level lock on the campaign folder ``root`` (created if absent) while the block
    runs: a second campaign into the same folder is refused at once, with a one-line error. The
    lock is ``flock`` on ``root/.droptower.lock``; the OS releases it when the process ends,
    however it ends, so a killed campaign never leaves a stale lock."""
    check_folder(root)  # a user's folder is refused before a lock file is put into it
    try:
        root.mkdir(parents=True, exist_ok=True)
        handle = open(root / LOCK_NAME, "a")
    except OSError as exc:
        raise WriteError.from_os_error(exc, root) from None
    try:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise DroptowerError("another droptower campaign is running in this folder (it holds "
                                 f"{LOCK_NAME}); wait for it to end, or choose another `out` folder",
                                 file=root) from None
        yield
    finally:
        handle.close()  # releases the lock


def open_folder(layout: Layout, spec: CampaignSpec, resume: bool) -> tuple[dict[str, Any] | None, list[str]]:
    """Check that the campaign may write into ``layout.root``; create it if new.

    Returns the existing manifest (None for a new folder) and warnings (other package
    versions than the folder was started with). A folder holding a campaign needs ``resume``
    and the same identity; a non-empty folder without a manifest is refused.
    """
    root = layout.root
    check_folder(root)
    if layout.manifest.is_file():
        old = read_manifest(layout.manifest)
        done = count_finished(layout)
        if not resume:
            raise DroptowerError(f"holds a campaign already ({done} of {len(old.get('tests', []))} tests finished); "
                                 "add `resume` to continue it, or choose another `out` folder", file=root)
        differ = _differences(old, spec)
        if differ:
            raise DroptowerError(f"holds a different campaign (its {', '.join(differ)} differ from the given ones); "
                                 "nothing was changed: choose another `out` folder", file=root)
        for stray in [*root.glob(".*.tmp"), *layout.records.glob(".*.tmp"), *layout.logs.glob(".*.tmp")]:
            stray.unlink(missing_ok=True)  # a temporary file of a write that was killed before its rename
        warnings = [f"{root}: campaign started with {name} {was}, continuing with {now}"
                    for name, now in versions().items()
                    if (was := old.get("versions", {}).get(name)) is not None and was != now]
        return old, warnings
    try:
        layout.records.mkdir(parents=True, exist_ok=True)
        layout.logs.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise DroptowerError(f"cannot create the campaign folder ({exc.strerror or exc})", file=root) from None
    return None, []


def write_manifest(layout: Layout, spec: CampaignSpec, status: dict[int, dict[str, Any]],
                   created: str | None = None) -> None:
    """The manifest: identity, inputs, settings, versions and per-test status.

    status: test_id -> ``{"status": "done" | "failed", "error": ..., "log_file": ...}`` for
    finished tests; every other test of the plan is ``pending``.
    """
    now = datetime.now(timezone.utc).isoformat(timespec="seconds")
    tests = []
    for test_id in spec.tests["test_id"].tolist():
        entry = status.get(test_id, {"status": "pending"})
        tests.append({"test_id": test_id, "status": entry["status"], "log_file": entry.get("log_file"),
                      "error": entry.get("error")})
    counts = {s: sum(t["status"] == s for t in tests) for s in ("done", "failed", "pending")}
    write_json(layout.manifest, {
        "format": FORMAT, "format_version": FORMAT_VERSION,
        "created": created or now, "updated": now,
        "hashes": spec.hashes(),
        "inputs": spec.inputs,
        "settings": spec.settings,
        "versions": versions(),
        "summary": {"n_tests": len(tests), **counts},
        "tests": tests,
    })


def read_record(path: Path) -> dict[str, Any] | None:
    """A test's result record, or None if it is absent or unreadable (then the test is redone)."""
    try:
        record = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError, RecursionError):
        return None
    return record if isinstance(record, dict) and record.get("status") in ("done", "failed") else None


def finished(layout: Layout, spec: CampaignSpec) -> dict[int, dict[str, Any]]:
    """test_id -> record of every finished test of the plan."""
    return {record["test_id"]: record for batch in finished_batches(layout, spec) for record in batch}


#: Records read at once when a large campaign's records are gone through (a 45 000-test
#: campaign's records as Python objects would take about half a gigabyte).
RECORD_BATCH = 5000


def finished_batches(layout: Layout, spec: CampaignSpec, size: int = RECORD_BATCH) -> Iterator[list[dict[str, Any]]]:
    """The records of the plan's finished tests, in plan order, ``size`` tests of the plan at a time."""
    ids = spec.tests["test_id"].tolist()
    for start in range(0, len(ids), size):
        batch = []
        for test_id in ids[start:start + size]:
            record = read_record(layout.record(test_id))
            if record is not None and record.get("test_id") == test_id:
                batch.append(record)
        yield batch
