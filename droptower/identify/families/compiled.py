"""Couplings of many parameter sets built from each element's compiled numbers, kept per element.

A family's :meth:`~droptower.identify.families.base.Family.batch` is called once per core call
of an identification (every candidate batch, every forward-difference Jacobian): building each
row's coupling anew (:func:`~droptower.rheology.parse_coupling`: the file's validation, every
element's compilation, a :class:`~droptower.rheology.Coupling` per row and one more for the
stack) cost as much CPU as a cheap coupling's simulation. A Jacobian's column moves one
parameter, so all but one element of its row are those of the row it was shifted from.

:class:`ElementCache` keeps, per element table (its fields exactly: each number by its type
and bits, :func:`frozen`), the validated spec and its compiled kernel elements. An element met
for the first time is validated by the coupling file's own model
(:class:`~droptower.rheology.loader.CouplingFile`, with the row's file header: refused as the
file refuses it) and compiled by its spec. A row's parameter vector is the concatenation of its
kernels' parameters, as :class:`~droptower.rheology.Coupling` concatenates them: the same
numbers to the last bit. Only accepted elements are kept; a refused row raises the
:class:`~droptower.errors.DroptowerError` of the file's validation (the engine's fallback,
:func:`~droptower.identify.engine.problem.admissible_couplings`, then builds its rows one by one).
"""
from __future__ import annotations

import pickle
import threading
from collections import OrderedDict
from typing import Any

import numpy as np

from droptower.config_validation import validate
from droptower.errors import DroptowerError
from droptower.limits import MAX_ELEMENTS
from droptower.rheology import Coupling, parse_coupling
from droptower.rheology.elements import ElementSpec, KernelElement
from droptower.rheology.loader import CouplingFile

#: Element tables kept (the least recently used dropped first): a Jacobian reuses the elements
#: of the row it shifts, met one call before.
CACHE_SIZE = 4096
#: The fields of a coupling file besides its elements (validated once per distinct header).
HEADER = ("name", "description", "source", "units")


def frozen(value: Any) -> bytes:
    """A key of an element table that tells apart whatever validation or compilation could tell
    apart: its pickle, which holds each number's type and bits (0.0 and -0.0 differ) and the
    fields in their order. (Two equal tables may have two keys, e.g. where one holds an object
    twice: a second compilation of the same numbers, never a wrong one.)"""
    return pickle.dumps(value, protocol=pickle.HIGHEST_PROTOCOL)


class ElementCache:
    """Validated and compiled elements by their tables' keys (:func:`frozen`), the least recently
    used dropped beyond ``size`` entries. An entry: (spec, its kernel elements, their parameters
    concatenated, the layout (codes, parameter sizes, state sizes))."""

    def __init__(self, size: int = CACHE_SIZE):
        self.size = size
        self._entries: OrderedDict[Any, tuple] = OrderedDict()
        self._headers: set[tuple] = set()
        self._lock = threading.Lock()  # identifications may run on several threads of one process

    def __len__(self) -> int:
        return len(self._entries)

    def clear(self) -> None:
        """Forget every element and header."""
        with self._lock:
            self._entries.clear()
            self._headers.clear()

    def get(self, key: Any) -> tuple | None:
        """The entry of ``key`` (marked as used), or None."""
        with self._lock:
            entry = self._entries.get(key)
            if entry is not None:
                self._entries.move_to_end(key)
            return entry

    def put(self, key: Any, spec: ElementSpec, kernels: list[KernelElement]) -> tuple:
        """Keep the compiled element ``spec`` (``kernels``: what its ``compile()`` returned) under ``key``."""
        layout = (tuple(k.code for k in kernels), tuple(k.params.size for k in kernels),
                  tuple(k.n_state for k in kernels))
        params = np.concatenate([k.params for k in kernels]) if kernels else np.zeros(0)
        entry = (spec, list(kernels), params, layout)
        with self._lock:
            self._entries[key] = entry
            if len(self._entries) > self.size:
                self._entries.popitem(last=False)
        return entry

    def row(self, data: dict[str, Any]) -> list[tuple]:
        """The entries of the elements of one coupling file ``data`` (validated and compiled where
        not kept yet; every element of a file whose header is new). :class:`DroptowerError` where
        the file's validation refuses it."""
        tables = data["element"]
        header = {k: data[k] for k in HEADER if k in data}
        known = tuple(header.items()) in self._headers
        keys = [frozen(t) for t in tables]
        entries = [self.get(k) if known else None for k in keys]
        missing = [i for i, e in enumerate(entries) if e is None]
        if missing:
            specs = validate(CouplingFile, {**header, "element": [tables[i] for i in missing]}, None).element
            compiled = [spec.compile() for spec in specs]  # every spec validated before one compiles, as a file's
            for i, spec, kernels in zip(missing, specs, compiled):
                entries[i] = self.put(keys[i], spec, kernels)
            self._headers.add(tuple(header.items()))
        return entries  # type: ignore[return-value]


#: The process's one cache (an element's validation and compilation depend on its table alone).
ELEMENTS = ElementCache()


def stacked(files: list[dict[str, Any]], cache: ElementCache = ELEMENTS) -> Coupling:
    """One coupling whose parameter sets are those of the coupling ``files`` (each a dict
    :func:`~droptower.rheology.parse_coupling` reads, one per parameter set): what
    ``Coupling.stack([parse_coupling(f) for f in files])`` builds (its elements and kernels the
    first file's), each distinct element validated and compiled once.

    Raises :class:`DroptowerError` where a file is refused (an element the file's validation
    refuses, too many state variables) or its structure differs from the first one's, as that
    stack does (the other files' layout is the first's, so the first's check of the state
    variables' limit holds for all).
    """
    rows: list[np.ndarray] = []
    first: tuple | None = None
    for data in files:
        tables = data.get("element")
        if not isinstance(tables, list) or not tables or len(tables) > MAX_ELEMENTS:
            parse_coupling(data)  # the file's own error
        entries = cache.row(data)
        layout = tuple(sum((e[3][j] for e in entries), ()) for j in range(3))
        if first is None:  # its layout (and the limit of state variables) is checked as the coupling is made
            first = (data, entries, layout)
        elif layout != first[2]:
            raise DroptowerError("couplings to stack must have the same element structure")
        # Coupling's own concatenation of its kernels' parameters (then float64): the same numbers
        rows.append(np.concatenate([e[2] for e in entries]).astype(np.float64))
    data, entries, _ = first  # type: ignore[misc]
    specs = [e[0] for e in entries]
    # the header as parse_coupling sets it (validated strings; the file's defaults where absent)
    return Coupling.compiled(specs, [e[1] for e in entries], np.vstack(rows), name=str(data.get("name", "")),
                             description=str(data.get("description", "")), source=str(data.get("source", "")),
                             units=str(data.get("units", "torsional")))
