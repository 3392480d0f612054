"""mkdocs hook: the API reference pages list every name of their package's ``__all__``.

A page holds the marker ``<!-- api: droptower.PACKAGE -->``; the hook replaces it with one
mkdocstrings block per name (by the object's defining module, so a re-exported name is
documented where it lives) and, for data (a dict or a constant), the ``#:`` comment above its
assignment. The reference therefore follows ``__all__`` without a hand-kept list;
``tests/test_api_docs.py`` checks that every name is covered and documented.
"""
from __future__ import annotations

import importlib
import inspect
import re
from pathlib import Path

MARKER = re.compile(r"<!-- api: ([\w.]+) -->")
ROOT = Path(__file__).resolve().parents[1]


def data_comment(package: str, name: str) -> str | None:
    """The ``#:`` comment block above the assignment of ``name`` in ``package``'s source files
    (None when there is none)."""
    module = importlib.import_module(package)
    folder = Path(module.__file__).parent
    files = sorted(folder.rglob("*.py")) if module.__file__.endswith("__init__.py") else [Path(module.__file__)]
    pattern = re.compile(rf"((?:^[ \t]*#:.*\n)+)^{re.escape(name)}\s*[:=]", re.M)
    for path in files:
        found = pattern.search(path.read_text(encoding="utf-8"))
        if found:
            return " ".join(line.strip()[2:].strip() for line in found.group(1).splitlines())
    return None


def target(package: str, name: str) -> str | None:
    """Where mkdocstrings finds ``package.name``: its defining module and qualified name, or
    None for data (rendered from its ``#:`` comment)."""
    obj = getattr(importlib.import_module(package), name)
    if inspect.isclass(obj) or inspect.isfunction(obj):
        return f"{obj.__module__}.{obj.__qualname__}"
    return None


#: the packages of the API reference, in the order of its pages: an object exported by several is
#: documented in full on the first one's page and linked from the others
PACKAGES = ("droptower.rheology", "droptower.rig", "droptower.servo", "droptower.io", "droptower.extract",
            "droptower.maps", "droptower.campaign", "droptower.compare", "droptower.design", "droptower.planner",
            "droptower.identify", "droptower.identify.families", "droptower.identify.engine",
            "droptower.fmu", "droptower.uncertainty", "droptower.data",
            "droptower")


def home(where: str) -> str:
    """The first package of :data:`PACKAGES` that exports the object at ``where``."""
    for package in PACKAGES:
        if any(target(package, name) == where for name in importlib.import_module(package).__all__):
            return package
    raise ValueError(f"{where} is exported by no package of the reference")


def summary(package: str, name: str) -> str:
    """The first line of the docstring of ``package.name``."""
    doc = inspect.getdoc(getattr(importlib.import_module(package), name)) or ""
    return doc.split("\n\n")[0].replace("\n", " ").replace("|", "\\|")


def api_markdown(package: str) -> str:
    """The reference of every name in ``package.__all__``, in its order."""
    module = importlib.import_module(package)
    blocks = []
    for name in module.__all__:
        where = target(package, name)
        if where is not None and home(where) != package:
            blocks.append(f"## `{name}`\n\n[`{name}`][{where}] (`{where}`): {summary(package, name)}\n")
        elif where is None:
            comment = data_comment(package, name) or ""
            value = getattr(module, name)
            kind = type(value).__name__
            shown = f" = `{value!r}`" if isinstance(value, (str, int, float)) else f" ({kind})"
            blocks.append(f"## `{name}`\n\n`{package}.{name}`{shown}\n\n{comment}\n")
        else:
            blocks.append(f"::: {where}\n    options:\n      heading: \"{name}\"\n      toc_label: \"{name}\"\n")
    return "\n".join(blocks)


def on_page_markdown(markdown: str, page, config, files) -> str:  # noqa: ARG001 (mkdocs' hook signature)
    """Replace every API marker of a page by its package's reference."""
    return MARKER.sub(lambda m: api_markdown(m.group(1)), markdown)
