"""Reference data shipped inside the package, found after any install (nothing beside the checkout needed).

- ``rapp2022_table4_map.csv``: Rapp et al.'s (2022) measured map (Experimental Mechanics 62
  (2022) 823-836, Table 4); the source notice is ``README.md`` beside it.
"""
from __future__ import annotations

from importlib import resources
from pathlib import Path

import pandas as pd

__all__ = ["TABLE4_NAME", "read_table4", "table4_path"]

#: Name under which ``droptower map`` (and :func:`droptower.maps.read_results`) accepts Table 4.
TABLE4_NAME = "rapp2022_table4"


def table4_path() -> Path:
    """Path of the shipped Table 4 of Rapp et al. 2022 (CSV, one row per measured point)."""
    return Path(str(resources.files(__name__).joinpath("rapp2022_table4_map.csv")))


def read_table4() -> pd.DataFrame:
    """Table 4 of Rapp et al. 2022: case, inertia_kgm2, drop_mass_kg, amplitude_deg, frequency_hz,
    stiffness_nm_per_deg (N·m/deg), damping_ratio."""
    return pd.read_csv(table4_path())
