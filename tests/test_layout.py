"""The package layout: renamed modules keep their old import paths for one release (with a
DeprecationWarning), and importing identification does not load the pymunk scene."""
from __future__ import annotations

import importlib
import subprocess
import sys
import warnings

import pytest

import droptower
from droptower._moved import MOVED_MODULES


@pytest.mark.parametrize("old", sorted(MOVED_MODULES))
def test_an_old_module_path_is_the_new_module_and_warns(old):
    new = MOVED_MODULES[old]
    sys.modules.pop(old, None)  # a previous import would return without the finder's warning
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        module = importlib.import_module(old)
    assert module is importlib.import_module(new)
    assert [w for w in caught if issubclass(w.category, DeprecationWarning) and new in str(w.message)]
    sys.modules.pop(old, None)


def test_the_new_module_files_exist_and_the_old_ones_are_gone():
    """A rename, not a copy: an old file left behind would shadow nothing but confuse a reader."""
    root = droptower.__path__[0]
    from pathlib import Path
    for old, new in MOVED_MODULES.items():
        assert Path(root, *new.split(".")[1:]).with_suffix(".py").is_file(), new
        assert not Path(root, *old.split(".")[1:]).with_suffix(".py").exists(), old


def test_an_unknown_module_is_still_refused():
    with pytest.raises(ModuleNotFoundError):
        importlib.import_module("droptower.rig.no_such_module")
