"""droptower: a virtual drop-tower impact rig and parameter extractor for elastomer couplings.

Data flows one way: config -> model (:mod:`droptower.rheology`) -> simulation
(:mod:`droptower.rig`, :mod:`droptower.servo`) -> log (:mod:`droptower.io`) -> extraction
(:mod:`droptower.extract`) -> map (:mod:`droptower.maps`) -> comparison. SI units inside.
"""
from droptower.errors import DroptowerError
from droptower.rheology import Coupling, CouplingState, load_coupling

__version__ = "0.1.0"
__all__ = ["Coupling", "CouplingState", "DroptowerError", "load_coupling", "__version__"]
