"""Test helper: a lab's own folder of drop-test logs, as a lab exports it (not as droptower writes
logs). The generator is the package's :mod:`droptower.campaign.lab_export` (public, documented:
"write a virtual campaign as a lab's export, to rehearse the evaluation"); this module re-exports
it under the names the tests use."""
from __future__ import annotations

from droptower.campaign.lab_export import (FIXTURES, GERMAN, HEIGHTS_MM, IMPERIAL, LAB_RIG_TOML, MASSES, REPEATS,
                                           LabDialect, LabFolder, _write_csv, _write_sheet, write_lab_folder)

Dialect = LabDialect  # the name the tests knew it by

__all__ = ["Dialect", "FIXTURES", "GERMAN", "HEIGHTS_MM", "IMPERIAL", "LAB_RIG_TOML", "LabDialect", "LabFolder", "MASSES",
           "REPEATS", "write_lab_folder", "_write_csv", "_write_sheet"]
