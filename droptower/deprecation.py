"""Old names kept for one release: each warns with a :class:`DeprecationWarning` that names its
replacement, and still works.

One place for the three ways a name is retired: a renamed keyword argument
(:func:`renamed_keywords`), a renamed attribute or class of a module (:func:`moved_names`), and
a ``summary()`` that returned a dict and now returns text (:class:`TextReport`). Renamed modules
are answered by :mod:`droptower._moved`.
"""
from __future__ import annotations

import functools
import inspect
import warnings
from typing import Any, Callable, Mapping, TypeVar

F = TypeVar("F", bound=Callable[..., Any])


def warn_deprecated(old: str, new: str, stacklevel: int = 3) -> None:
    """Warn that ``old`` is deprecated in favour of ``new`` (by default at the caller's caller:
    the line that used the old name)."""
    warnings.warn(f"{old} is deprecated and will be removed in the next release: use {new}", DeprecationWarning,
                  stacklevel=stacklevel)


def renamed_attribute(owner: str, old: str, new: str) -> property:
    """A property ``old`` that reads and writes attribute ``new``, warning on each use
    (``owner``: the class's name in the message)."""

    def get(self: Any) -> Any:
        warn_deprecated(f"{owner}.{old}", f"{owner}.{new}")
        return getattr(self, new)

    def put(self: Any, value: Any) -> None:
        warn_deprecated(f"{owner}.{old}", f"{owner}.{new}")
        setattr(self, new, value)

    return property(get, put, doc=f"Deprecated: :attr:`{new}` (removed in the next release).")


def renamed_keywords(**old_to_new: str) -> Callable[[F], F]:
    """Accept each old keyword ``old`` of the decorated function as its new name, with a
    :class:`DeprecationWarning`; both given at once is a :class:`TypeError` (as Python says of a
    keyword given twice).

    Examples
    --------
    >>> @renamed_keywords(kind="family")
    ... def fit(family: str) -> str:
    ...     return family
    """

    def decorate(func: F) -> F:
        positions = {name: i for i, name in enumerate(inspect.signature(func).parameters)}

        @functools.wraps(func)
        def wrapper(*args: Any, **kwargs: Any) -> Any:
            for old, new in old_to_new.items():
                if old in kwargs:
                    if new in kwargs or positions.get(new, len(args)) < len(args):
                        raise TypeError(f"{func.__name__}() got {new!r} and its old name {old!r}: give {new!r}")
                    warn_deprecated(f"{func.__name__}({old}=...)", f"{func.__name__}({new}=...)")
                    kwargs[new] = kwargs.pop(old)
            return func(*args, **kwargs)

        wrapper.renamed_keywords = dict(old_to_new)  # type: ignore[attr-defined]
        return wrapper  # type: ignore[return-value]

    return decorate


def moved_names(module: str, renamed: Mapping[str, str], namespace: Mapping[str, Any]) -> Callable[[str], Any]:
    """A module ``__getattr__`` that answers each old name of ``renamed`` (old -> new) with the
    object now named ``new`` in ``namespace`` (the module's globals), with a DeprecationWarning."""

    def __getattr__(name: str) -> Any:
        if name in renamed:
            new = renamed[name]
            warn_deprecated(f"{module}.{name}", f"{module}.{new}")
            return namespace[new]
        raise AttributeError(f"module {module!r} has no attribute {name!r}")

    return __getattr__


class TextReport(str):
    """The text report a ``summary()`` returns, which for one release still answers the dict
    that ``summary()`` used to return: ``report["key"]``, ``.get``, ``.keys``, ``.items`` and
    ``.values`` warn (DeprecationWarning, use ``to_dict()``) and read that dict.

    It is a :class:`str` in every other respect (printed, compared, split, written).
    """

    _owner_dict: dict[str, Any]
    _where: str

    def __new__(cls, text: str, data: Mapping[str, Any], where: str) -> "TextReport":
        self = super().__new__(cls, text)
        self._owner_dict = dict(data)
        self._where = where
        return self

    def _old(self) -> dict[str, Any]:
        warn_deprecated(f"{self._where}.summary() read as a dict", f"{self._where}.to_dict()")
        return self._owner_dict

    def __getitem__(self, key: Any) -> Any:  # type: ignore[override]
        if isinstance(key, str):
            return self._old()[key]
        return str.__getitem__(self, key)

    def get(self, key: str, default: Any = None) -> Any:
        """Deprecated dict access (``to_dict().get``)."""
        return self._old().get(key, default)

    def keys(self) -> Any:
        """Deprecated dict access (``to_dict().keys``)."""
        return self._old().keys()

    def items(self) -> Any:
        """Deprecated dict access (``to_dict().items``)."""
        return self._old().items()

    def values(self) -> Any:
        """Deprecated dict access (``to_dict().values``)."""
        return self._old().values()
