"""Where the shipped presets live and how a name or path on the command line resolves.

``rig_configs/`` sits at the top of the repository and is installed as the package
``droptower.rig_configs``, so ``droptower`` finds its presets after any install. A user may
give a path (``my/coupling.toml``) or the name of a shipped preset (``rapp2022_nr60``).
"""
from __future__ import annotations

import tomllib
from importlib import resources
from pathlib import Path
from typing import Any

from droptower.errors import DroptowerError, missing_file, no_file_or_preset, readable_file, unreadable_file
from droptower.limits import MAX_CONFIG_BYTES, MAX_CONFIG_DEPTH, format_bytes, nesting_depth

#: Sub-folders of ``rig_configs``: couplings, rigs, test plans (design of experiments).
KINDS = ("couplings", "rigs", "doe")

DEFAULT_COUPLING = "rapp2022_nr60"
DEFAULT_RIG = "rapp2022"
DEFAULT_DOE = "rapp2022_table2"


def preset_dir(kind: str) -> Path:
    """The folder of shipped presets of ``kind`` (``couplings``, ``rigs`` or ``doe``).

    Installed, they are the package ``droptower.rig_configs``; run from a source checkout
    (``droptower`` imported from the repository, e.g. by the tests), ``rig_configs/`` beside it.
    """
    if kind not in KINDS:
        raise ValueError(f"unknown preset kind {kind!r}")
    try:
        root = Path(str(resources.files("droptower.rig_configs")))
    except ModuleNotFoundError:
        root = Path(__file__).resolve().parents[1] / "rig_configs"
    return root / kind


def list_presets(kind: str) -> list[str]:
    """Names (file stems) of the shipped presets of ``kind``."""
    return sorted(p.stem for p in preset_dir(kind).glob("*.toml"))


def resolve(name_or_path: str | Path, kind: str) -> Path:
    """A path to a TOML file: an existing path, or the name of a shipped preset."""
    path = Path(name_or_path)
    if path.is_file():
        return path
    preset = preset_dir(kind) / f"{Path(str(name_or_path)).stem}.toml"
    if preset.is_file() and path.suffix in ("", ".toml") and len(path.parts) <= 2:
        return preset
    if path.exists():  # a folder
        raise missing_file(path)
    raise no_file_or_preset(name_or_path, f"{kind[:-1] if kind != 'doe' else 'test plan'} preset", list_presets(kind))


def display_name(path: str | Path | None, kind: str) -> str | None:
    """How a message names a config file: a shipped preset by its name (``rapp2022``, the
    name a user gives), any other file by its path as given."""
    if path is None:
        return None
    path = Path(path)
    try:
        if path.resolve().parent == preset_dir(kind).resolve():
            return path.stem
    except OSError:
        pass
    return str(path)


def read_toml(path: str | Path) -> dict[str, Any]:
    """Parse a TOML file; an unreadable or malformed file is a one-line DroptowerError."""
    path = readable_file(path)
    try:
        with path.open("rb") as fh:
            text = fh.read(MAX_CONFIG_BYTES + 1)
        if len(text) > MAX_CONFIG_BYTES:  # a config is a few kB: this is not one (and would parse for minutes)
            raise DroptowerError(f"larger than {format_bytes(MAX_CONFIG_BYTES)}: not a configuration file", file=path)
        data = tomllib.loads(text.decode("utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise DroptowerError(f"not valid TOML ({exc})", file=path) from None
    except RecursionError:  # the parser recurses once per nested array or inline table
        raise DroptowerError(f"nested too deeply (more than {MAX_CONFIG_DEPTH} levels of arrays or tables)",
                             file=path) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise unreadable_file(path, exc) from None
    if nesting_depth(data) > MAX_CONFIG_DEPTH:
        raise DroptowerError(f"nested too deeply (more than {MAX_CONFIG_DEPTH} levels of arrays or tables)", file=path)
    return data
