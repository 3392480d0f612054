"""Regenerate every figure the tests store, with the code as it stands:

    python tests/regenerate.py

Runs the tests marked ``regression`` (those using the ``regression`` fixture, tests/regression.py)
with ``--regenerate``, which rewrites ``tests/data/regression/*.json``, then the campaign
reference values (``tests/data/campaign_reference/regenerate.py``). Run it only when a change
is meant to move the figures, and say in the commit which change and why; review the diff.
Extra arguments go to pytest (``-k convergence`` regenerates a part).
"""
from __future__ import annotations

import runpy
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent


def main(argv: list[str]) -> int:
    # one process (-n 0): the tests of one module write the same file
    code = subprocess.call([sys.executable, "-m", "pytest", str(HERE), "-n", "0", "-q", "-m", "regression",
                            "--regenerate", "-p", "no:cacheprovider", *argv], cwd=HERE.parent)
    if code != 0 or argv:
        return code
    runpy.run_path(str(HERE / "data" / "campaign_reference" / "regenerate.py"), run_name="__main__")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
