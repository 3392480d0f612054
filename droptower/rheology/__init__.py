"""The rheological core: the coupling models of docs/theory.md#elements as fast, composable elements.

- :mod:`.elements`: the element kinds of a coupling file (validated specs);
- :mod:`.kernels`: their compiled per-step updates (numba), with energy accounting;
- :mod:`.kinds`: one record per kernel kind (layout with named slots, step, bounds);
- :mod:`.slots`: the kernels' named slot offsets, generated from the records;
- :mod:`.coupling`: :class:`Coupling`, explicit state and time step, batch axis first;
- :mod:`.loader`: TOML files -> :class:`Coupling`.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

from droptower.lazy_names import lazy_names

if TYPE_CHECKING:
    from droptower.rheology.coupling import Coupling, CouplingState, Response
    from droptower.rheology.loader import coupling_to_toml, load_coupling, parse_coupling

#: name -> module, imported on first use: a module that needs only the kernel cache
#: (:mod:`.numba_cache`, e.g. the decay fit's kernels) loads no coupling, pydantic or core kernels
_LAZY: dict[str, str] = {"Coupling": "droptower.rheology.coupling", "CouplingState": "droptower.rheology.coupling",
                         "Response": "droptower.rheology.coupling", "coupling_to_toml": "droptower.rheology.loader",
                         "load_coupling": "droptower.rheology.loader", "parse_coupling": "droptower.rheology.loader"}

__all__ = ["Coupling", "CouplingState", "Response", "load_coupling", "parse_coupling", "coupling_to_toml"]


__getattr__, __dir__ = lazy_names(__name__, _LAZY, globals())
