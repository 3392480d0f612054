"""The model families of the source papers, one module each (its parameters and its strategy).

Families (docs/theory.md#elements): ``zerodim6`` and ``zerodim20`` (the zero-dimensional model paper), ``elastoslide`` (the elastoslide paper),
``pfeffer`` (Scheiblegger et al. 2013), ``masing`` (Heine & Plagemann 2014), ``overlay`` (Rapp et al.'s (2022) map), ``template`` (any
coupling file, its numbers scaled), ``filled_rubber`` (a generic filled elastomer, docs/theory.md#filled-rubber). Every module
holds the family class (parameters, bounds, first guess, coupling) and its staged
identification strategy; :mod:`.base` the family base class, :mod:`.stages` the stages they
share.
"""
from __future__ import annotations

from typing import Callable

from droptower.errors import DroptowerError
from droptower.identify.families import (elastoslide, filled_rubber, masing, overlay, pfeffer, template, zerodim6,
                                         zerodim20)
from droptower.identify.families.base import COMMON_OPTIONS, Family
from droptower.identify.families.elastoslide import ElastoslideFamily, loading_curve
from droptower.identify.families.filled_rubber import FilledRubberFamily
from droptower.identify.families.masing import MasingFamily
from droptower.identify.families.overlay import OverlayFamily
from droptower.identify.families.pfeffer import PfefferFamily
from droptower.identify.families.template import TemplateFamily
from droptower.identify.families.zerodim6 import ZeroDim6
from droptower.identify.families.zerodim20 import ZeroDim20
from droptower.identify.result import Identification

_MODULES = (zerodim6, zerodim20, elastoslide, pfeffer, masing, overlay, template, filled_rubber)
#: every model family by its name (``zerodim6``, ``elastoslide``, ...): name -> family class
FAMILIES: dict[str, type[Family]] = {m.FAMILY.kind: m.FAMILY for m in _MODULES}
#: each family's staged identification strategy by the family's name
STRATEGIES: dict[str, Callable[..., Identification]] = {m.FAMILY.kind: m.strategy for m in _MODULES}


def family_class(kind: str) -> type[Family]:
    """The family of a model name (``zerodim6``, ...); a one-line error for an unknown one."""
    if kind not in FAMILIES:
        raise DroptowerError(f"unknown model kind {kind!r} (known: {', '.join(FAMILIES)})")
    return FAMILIES[kind]


__all__ = ["COMMON_OPTIONS", "FAMILIES", "STRATEGIES", "ElastoslideFamily", "Family", "FilledRubberFamily", "MasingFamily", "OverlayFamily",
           "PfefferFamily", "TemplateFamily", "ZeroDim20", "ZeroDim6", "family_class", "loading_curve"]
