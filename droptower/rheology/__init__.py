"""The rheological core: the coupling models of docs/theory.md#elements as fast, composable elements.

- :mod:`.elements`: the element kinds of a coupling file (validated specs);
- :mod:`.kernels`: their compiled per-step updates (numba), with energy accounting;
- :mod:`.kinds`: one record per kernel kind (layout with named slots, step, bounds);
- :mod:`.slots`: the kernels' named slot offsets, generated from the records;
- :mod:`.coupling`: :class:`Coupling`, explicit state and time step, batch axis first;
- :mod:`.loader`: TOML files -> :class:`Coupling`.
"""
from droptower.rheology.coupling import Coupling, CouplingState, Response
from droptower.rheology.loader import coupling_to_toml, load_coupling, parse_coupling

__all__ = ["Coupling", "CouplingState", "Response", "load_coupling", "parse_coupling", "coupling_to_toml"]
