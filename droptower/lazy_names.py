"""A package's public names imported on first use (PEP 562), so importing the package loads
only what its caller uses (docs/conventions.md; ``tests/test_cold_start.py`` checks which modules
a fresh interpreter holds).

A package keeps one table ``name -> module`` (or ``name -> (module, attribute)`` where the
attribute has another name) and gets its module-level ``__getattr__`` and ``__dir__`` from
:func:`lazy_names`.
"""
from __future__ import annotations

import importlib
from typing import Any, Callable, Mapping


def lazy_names(package: str, table: Mapping[str, str | tuple[str, str]], namespace: dict[str, Any]
               ) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """The ``(__getattr__, __dir__)`` pair of ``package``.

    Parameters
    ----------
    package : str
        The package's ``__name__`` (named in the AttributeError of an unknown name).
    table : mapping
        Public name -> the module that defines it, or -> ``(module, attribute)``.
    namespace : dict
        The package's ``globals()``: a name imported once is stored there, so later look-ups
        do not reach ``__getattr__`` again.
    """
    def __getattr__(name: str) -> Any:
        """Import a public name on first use (PEP 562)."""
        try:
            where = table[name]
        except KeyError:
            raise AttributeError(f"module {package!r} has no attribute {name!r}") from None
        module, attribute = (where, name) if isinstance(where, str) else where
        value = getattr(importlib.import_module(module), attribute)
        namespace[name] = value
        return value

    def __dir__() -> list[str]:
        return sorted(set(namespace) | set(table))

    return __getattr__, __dir__
