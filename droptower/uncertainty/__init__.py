"""Measurement uncertainty of drop-tower results (GUM, JCGM 100:2008; Monte Carlo, JCGM 101:2008;
docs/guide/uncertainty.md).

The rig's input uncertainties (:class:`RigUncertainty`, the rig file's ``[uncertainty]``
table, with :func:`override_uncertainty` over it: the command line's ``NAME=VALUE[:distribution]``) and the fit's covariance are propagated through the extraction's own closed forms:

- :mod:`.inputs`: the rig's stated uncertainties resolved for one drop (:func:`drop_inputs`);
- :mod:`.model`: the measurement model of one drop (:class:`DropModel`);
- :mod:`.gum`: the law of propagation, sensitivities and contributions (:func:`propagate_gum`);
- :mod:`.montecarlo`: propagation of distributions, adaptive (:func:`propagate_monte_carlo`);
- :mod:`.budget`: one drop's budget, the method chosen by validation (:func:`drop_budget`);
- :mod:`.conditions`: each condition's mean with its budget, which input dominates (:func:`condition_budgets`);
- :mod:`.table`: ``*_u``, ``*_U95`` and the dominant input in per-drop tables (:func:`with_uncertainty`);
  a campaign's budgets with the GUM validated once per condition (:func:`campaign_budgets`);
- :mod:`.mapband`: the map's coefficients and predictions with the fit's and the inputs' shares, the
  inputs correlated across the drops that share them (:func:`map_uncertainty`);
- :mod:`.agreement`: E_n numbers and verdicts against a bench (ISO 13528, :func:`en_verdicts`), per
  servo point of a validated route (:func:`route_agreement`);
- :mod:`.route`: the inputs' shares of the model route, each input's shift of a drop-test
  identification (:func:`route_input_sets`);
- :mod:`.bench`: the servo bench's own U95 from its cycles' scatter and its calibrations (:func:`bench_u95`).
"""
from droptower.rig.uncertainty import (FixtureUncertainty, InputUncertainty, RigUncertainty, override_uncertainty,
                                       parse_uncertainty_spec)
from droptower.uncertainty.bench import bench_u95
from droptower.uncertainty.route import route_input_sets
from droptower.uncertainty.agreement import (AGREEMENT_QUANTITIES, VERDICTS, en_number, en_verdicts, format_agreement,
                                             route_agreement)
from droptower.uncertainty.budget import DropBudget, QuantityUncertainty, coverage_factor, drop_budget
from droptower.uncertainty.conditions import condition_budgets
from droptower.uncertainty.gum import GumPropagation, propagate_gum
from droptower.uncertainty.inputs import INPUTS, DropInputs, Input, drop_inputs
from droptower.uncertainty.mapband import MapUncertainty, map_uncertainty
from droptower.uncertainty.model import QUANTITIES, DropModel
from droptower.uncertainty.montecarlo import MonteCarloPropagation, propagate_monte_carlo
from droptower.uncertainty.table import campaign_budgets, drop_budgets, uncertainty_columns, with_uncertainty

__all__ = ["AGREEMENT_QUANTITIES", "DropBudget", "DropInputs", "DropModel", "FixtureUncertainty", "GumPropagation", "INPUTS", "Input",
           "InputUncertainty", "MapUncertainty", "MonteCarloPropagation", "QUANTITIES", "QuantityUncertainty", "RigUncertainty",
           "VERDICTS", "bench_u95", "campaign_budgets", "condition_budgets", "coverage_factor", "drop_budget", "drop_budgets", "drop_inputs", "en_number", "en_verdicts", "format_agreement", "map_uncertainty", "override_uncertainty",
           "parse_uncertainty_spec", "propagate_gum",
           "propagate_monte_carlo", "route_agreement", "route_input_sets", "uncertainty_columns", "with_uncertainty"]
