"""One error type for everything a user can get wrong.

Every problem with input (a config, a log, a command-line value) is raised as
:class:`DroptowerError`. Its text is one line that names the file and the problem; the CLI
prints it without a traceback and exits with code 2. Batch commands catch it per file,
go on with the other files and list the failures at the end.

Messages speak Python: a value the user can give is named by its Python parameter or config
key in backticks (``give `inertia_kgm2` or `rig```, a channel role as
``roles={'angle': 'NAME[:UNIT]'}``), and ``where`` is the bare parameter name (``workers``).
The command line reports the same error with its own flags (:mod:`droptower.cli.flags`).

The situations every command meets (a missing or unreadable file, a value that must be
positive, an unknown preset, an output folder that cannot be made) are worded once, here, so
all commands say them alike.
"""
from __future__ import annotations

import math
import os
import re
from pathlib import Path


class DroptowerError(Exception):
    """A user-facing error: ``"<file>: <where>: <problem>"`` on one line.

    Parameters
    ----------
    problem:
        What is wrong, in words a test engineer understands.
    file:
        The file the problem is in (config, log), if any.
    where:
        The place inside the file: ``"element 3 (elastoslide): field p"``,
        ``"channel 'torque'"``, ``"row 12"``.
    """

    def __init__(self, problem: str, *, file: str | Path | None = None, where: str | None = None):
        self.problem = " ".join(str(problem).split())  # one line, always
        self.file = str(file) if file is not None else None
        self.where = where
        super().__init__(self.message)

    @property
    def message(self) -> str:
        parts = [p for p in (self.file, self.where, self.problem) if p]
        return ": ".join(parts)

    def with_file(self, file: str | Path) -> "DroptowerError":
        """The same error, attributed to ``file`` if it names no file yet."""
        if self.file is not None:
            return self
        return DroptowerError(self.problem, file=file, where=self.where)


class WriteError(DroptowerError):
    """The system refused to write a file (full disk, no permission, read-only file system)."""

    @classmethod
    def from_os_error(cls, exc: OSError, file: str | Path | None = None) -> "WriteError":
        """``exc`` in one line, named by ``file`` (else the file the OS names)."""
        code = exc.errno or next(map(int, re.findall(r"\[errno (\d+)\]", str(exc))), None)  # pyarrow: in the text
        reason = os.strerror(code) if code else (exc.strerror or str(exc))
        return cls(f"cannot write ({reason})", file=file if file is not None else exc.filename)


# One wording per situation, for every command (tests/test_messages.py walks them all).
def missing_file(path: str | Path) -> DroptowerError:
    """``<path>: no such file`` (``not a file`` for a folder or a device)."""
    return DroptowerError("not a file" if Path(path).exists() else "no such file", file=path)


def readable_file(path: str | Path) -> Path:
    """``path`` if it is a file this process can open, else the one-line error of :func:`missing_file`
    or :func:`unreadable_file` (one check for every reader: their own errors for it vary)."""
    path = Path(path)
    if not path.is_file():
        raise missing_file(path)
    try:
        with open(path, "rb"):
            pass
    except OSError as exc:
        raise unreadable_file(path, exc) from None
    return path


def unreadable_file(path: str | Path, detail: object, what: str | None = None) -> DroptowerError:
    """``<path>: cannot read (<what>: <detail>)``: the file is there but cannot be read as ``what``
    (an OSError's reason, or the parser's complaint)."""
    if isinstance(detail, OSError):
        detail = detail.strerror or detail
    text = " ".join(str(detail).split())
    return DroptowerError(f"cannot read ({what}: {text})" if what else f"cannot read ({text})", file=path)


def not_in_range(value: float, where: str, *, most: float | None = None, file: str | Path | None = None,
                 ) -> DroptowerError:
    """``<where>: must be > 0 [and at most <most>], got <value>``: a value that must be positive."""
    bound = f" and at most {most:g}" if most is not None else ""
    return DroptowerError(f"must be > 0{bound}, got {value:g}", file=file, where=where)


def check_positive(value: float | None, where: str, *, most: float | None = None) -> None:
    """Refuse a given value that is not finite and > 0 (and at most ``most``), in the one wording."""
    if value is not None and not (math.isfinite(value) and 0 < value <= (math.inf if most is None else most)):
        raise not_in_range(value, where, most=most)


def no_file_or_preset(name: str | Path, kind: str, presets: list[str]) -> DroptowerError:
    """``<name>: no such file, and no shipped <kind> of that name (shipped: a, b)``."""
    return DroptowerError(f"no such file, and no shipped {kind} of that name (shipped: {', '.join(presets) or 'none'})",
                          file=name)


def make_folder(path: str | Path) -> Path:
    """Create the output folder ``path`` (and its parents); a refusal is a :class:`WriteError`
    that blames the folder: ``<path>: cannot create the folder (<reason>)``."""
    path = Path(path)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        reason = os.strerror(exc.errno) if exc.errno else str(exc)
        raise WriteError(f"cannot create the folder ({reason})", file=path) from None
    return path


def finite_values(values, name: str, *, file: str | Path | None = None):
    """``values`` as a float array if every sample is finite, else ``<file>: <name>: sample <i> is
    NaN|inf (<n> of <N> non-finite; ...)``. droptower fills no gaps anywhere (the log readers'
    policy): a record with a gap is cut or interpolated by the user, never silently thinned.
    A value that is no number at all is refused as such."""
    import numpy as np

    try:
        array = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise DroptowerError(f"expected numbers, got {type(values).__name__}", file=file, where=name) from None
    bad = ~np.isfinite(array)
    if bad.any():
        first = np.unravel_index(int(np.argmax(bad)), array.shape)
        index = int(first[0]) if array.ndim == 1 else tuple(int(i) for i in first)
        kind = "NaN" if np.isnan(array[first]) else "infinite"
        raise DroptowerError(f"sample {index} is {kind} ({int(bad.sum())} of {array.size} non-finite; droptower fills "
                             "no gaps: cut the record or fill the gap first)", file=file, where=name)
    return array


def expects(**kinds: "str | type | list"):
    """Decorator: refuse a wrong-typed argument with one TypeError naming the function, the
    argument, what it expects and what it got, before it fails somewhere inside as an
    AttributeError. ``kinds``: argument name -> a class, a dotted class path (resolved at the first
    call, so no import cycle), a tuple of such (any of them), or ``[kind]`` for a list or tuple of
    such."""
    import functools
    import importlib
    import inspect

    def resolve(kind):
        if isinstance(kind, tuple):
            return tuple(resolve(k) for k in kind)
        if isinstance(kind, str):
            module, _, name = kind.rpartition(".")
            return getattr(importlib.import_module(module), name)
        return kind

    def _names(cls) -> str:
        return " or ".join(c.__name__ for c in cls) if isinstance(cls, tuple) else cls.__name__

    def wrap(func):
        signature = inspect.signature(func)

        @functools.wraps(func)
        def checked(*args, **kwargs):
            try:
                bound = signature.bind(*args, **kwargs)
            except TypeError as exc:
                raise TypeError(f"{func.__qualname__}: {exc}") from None
            for name, kind in kinds.items():
                if name not in bound.arguments:
                    continue
                value, many = bound.arguments[name], isinstance(kind, list)
                cls = resolve(kind[0] if many else kind)
                if many:
                    ok = isinstance(value, (list, tuple)) and all(isinstance(v, cls) for v in value)
                    wanted = f"a list of {_names(cls)}"
                else:
                    ok, wanted = isinstance(value, cls), f"a {_names(cls)}"
                if not ok:
                    raise TypeError(f"{func.__qualname__}: {name} must be {wanted}, got {type(value).__name__}")
            return func(*args, **kwargs)

        return checked

    return wrap
