"""droptower: a virtual drop-tower impact rig and parameter extractor for elastomer couplings.

Data flows one way: config -> model (:mod:`droptower.rheology`) -> simulation
(:mod:`droptower.rig`, :mod:`droptower.servo`) -> log (:mod:`droptower.io`) -> extraction
(:mod:`droptower.extract`) -> map (:mod:`droptower.maps`) -> comparison. SI units inside.

The core is imported on first use (numba is slow to import), so commands that only read logs
start fast.
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Any

from droptower.errors import DroptowerError

if TYPE_CHECKING:
    from droptower.rheology import Coupling, CouplingState, load_coupling

__version__ = "0.1.0"
__all__ = ["Coupling", "CouplingState", "DroptowerError", "load_coupling", "__version__"]

_LAZY = {"Coupling", "CouplingState", "load_coupling"}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        from droptower import rheology
        return getattr(rheology, name)
    raise AttributeError(f"module 'droptower' has no attribute {name!r}")
