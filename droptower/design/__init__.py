"""Designing a drop-tower campaign from what the engineer wants to measure.

:mod:`.coverage` (the target region, the hull a set of tests covers), :mod:`.choose` (levers,
masses and heights from the planner's predictions), :mod:`.repeats` (repeats for a target
uncertainty), :mod:`.identification` (the drops that identify a model best), :mod:`.outputs`
(the DOE TOML and the lab's run sheet); :func:`design` (:mod:`.designer`) is all of it in one call.
"""
from droptower.design.choose import Design, design_campaign, predict_candidates
from droptower.design.coverage import Target, covered_fraction, in_hull
from droptower.design.designer import design
from droptower.design.identification import IdentificationDesign

__all__ = ["Design", "IdentificationDesign", "Target", "covered_fraction", "design", "design_campaign", "in_hull",
           "predict_candidates"]
