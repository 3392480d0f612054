"""One error type for everything a user can get wrong.

Every problem with input (a config, a log, a command-line value) is raised as
:class:`DroptowerError`. Its text is one line that names the file and the problem; the CLI
prints it without a traceback and exits with code 2. Batch commands catch it per file,
go on with the other files and list the failures at the end.
"""
from __future__ import annotations

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
