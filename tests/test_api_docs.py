"""The API reference is complete: every name in each package's ``__all__`` resolves, has a
docstring (classes and functions: their own; data: a ``#:`` comment at its assignment), and
the reference pages list it (docs/hooks.py generates them from ``__all__``)."""
from __future__ import annotations

import importlib
import inspect
import pkgutil
import re
import sys
from pathlib import Path

import pytest

import droptower

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "docs"))
import hooks  # noqa: E402  (docs/hooks.py: the mkdocs hook that writes the API pages)

sys.path.remove(str(ROOT / "docs"))

PACKAGES = ["droptower"] + sorted(m.name for m in pkgutil.walk_packages(droptower.__path__, "droptower.")
                                  if m.ispkg and not m.name.startswith("droptower.cli"))


def _exported(package: str) -> list[str]:
    return list(getattr(importlib.import_module(package), "__all__", []))


def test_every_package_of_the_library_has_an_all_and_a_page():
    """Every package a user imports declares its public names and has a reference page (the
    command line and the report's page builder are not a Python API; the presets are data)."""
    internal = {"droptower.report", "droptower.rig_configs"}
    pages = (ROOT / "docs" / "api").glob("*.md")
    listed = {line.split("<!-- api: ")[1].split(" -->")[0] for p in pages for line in p.read_text().splitlines()
              if "<!-- api: " in line}
    for package in PACKAGES:
        if package in internal:
            continue
        assert _exported(package), f"{package} has no __all__"
        assert package in listed, f"{package} has no page in docs/api/"
    assert set(hooks.PACKAGES) == listed


@pytest.mark.parametrize("package", [p for p in PACKAGES if _exported(p)])
def test_every_exported_name_is_documented(package):
    module = importlib.import_module(package)
    undocumented = []
    for name in module.__all__:
        obj = getattr(module, name)  # an AttributeError here: a name in __all__ that does not exist
        if inspect.isclass(obj) or inspect.isfunction(obj):
            own = obj.__dict__.get("__doc__") if inspect.isclass(obj) else obj.__doc__
            if not own or len(own.strip()) < 20:
                undocumented.append(name)
        elif not hooks.data_comment(package, name):
            undocumented.append(f"{name} (data: needs a '#:' comment above its assignment)")
    assert not undocumented, f"{package}: no docstring for " + ", ".join(undocumented)


@pytest.mark.parametrize("package", [p for p in PACKAGES if _exported(p)])
def test_the_reference_lists_every_exported_name(package):
    page = hooks.api_markdown(package)
    for name in importlib.import_module(package).__all__:
        where = hooks.target(package, name)
        assert (f"::: {where}\n" in page or f"[`{name}`][{where}]" in page) if where else f"## `{name}`" in page, name


def test_the_curated_namespace_is_lazy_and_complete():
    """``import droptower`` imports no heavy package (numba, pandas, pymunk) until a name is used;
    every name it offers resolves to the object of its package."""
    import subprocess

    code = ("import sys, droptower; heavy = [m for m in ('numba', 'pandas', 'pymunk', 'scipy') if m in sys.modules]; "
            "print(','.join(heavy))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "", done.stdout
    for name in droptower.__all__:
        assert getattr(droptower, name) is not None
    assert droptower.fit_map is importlib.import_module("droptower.maps").fit_map
    assert set(dir(droptower)) >= set(droptower.__all__)
    assert set(droptower.__all__) == {"DroptowerError", "__version__", *droptower._LAZY}
    with pytest.raises(AttributeError, match="no attribute 'nonexistent'"):
        droptower.nonexistent  # noqa: B018


def test_no_name_of_the_namespace_is_shadowed_by_a_subpackage():
    """Importing ``droptower.X`` binds ``droptower.X`` to the module: a function of that name
    in the curated namespace would silently turn into the module."""
    modules = {m.name for m in pkgutil.iter_modules(droptower.__path__)}
    assert not modules & set(droptower.__all__)


#: the curated names whose docstrings are in numpydoc sections so far (the others still describe
#: their parameters in prose); each must name every parameter of its signature
NUMPYDOC = ("load_rig", "load_doe", "simulate", "plan", "read_log", "read_results", "fit_map")


def _numpydoc_sections(doc: str) -> dict[str, str]:
    parts = re.split(r"^(\w[\w ]*)\n-{3,}\n", doc, flags=re.M)
    return {parts[i].strip(): parts[i + 1] for i in range(1, len(parts) - 1, 2)}


@pytest.mark.parametrize("name", [n for n in droptower.__all__ if callable(getattr(droptower, n))])
def test_numpydoc_sections_name_every_parameter(name):
    obj = getattr(droptower, name)
    sections = _numpydoc_sections(inspect.getdoc(obj) or "")
    if name in NUMPYDOC:
        assert {"Parameters", "Returns"} <= set(sections), f"{name}: no numpydoc Parameters / Returns section"
    if "Parameters" in sections:
        documented = set(re.findall(r"^(\w+) ?:", sections["Parameters"], re.M))
        wanted = {p for p in inspect.signature(obj).parameters if p not in ("self", "args", "kwargs")}
        assert documented == wanted, f"{name}: documented {sorted(documented)}, signature {sorted(wanted)}"
