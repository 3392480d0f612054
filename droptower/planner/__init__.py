"""The interactive planner page: one self-contained offline HTML file for the lab.

:mod:`.grid` predicts every drop of the rig on a grid (every lever x mass x log-spaced height x
preload, :func:`droptower.rig.predictions.plan` in one batch) and the candidates ``droptower design``
chooses from; :mod:`.page` embeds them as JSON with plotly.js and ``planner.js``, which
interpolates the grid in log height and repeats the design's selection in the browser.
"""
from droptower.planner.grid import planner_data
from droptower.planner.page import write_planner

__all__ = ["planner_data", "write_planner"]
