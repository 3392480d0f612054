"""Campaigns: a whole test plan simulated on the virtual drop tower, logged and extracted on the
one data path real logs take (``droptower campaign``; Rapp et al. 2022, Table 2, docs/theory.md#rig).

``run_campaign(out, rig, coupling, doe, workers=..., scheduler=..., resume=...)`` fills a
folder with one log and one result record per test, a manifest and the results table
(:mod:`.folder` describes the layout). Modules: :mod:`.spec` (inputs, settings, identity),
:mod:`.chunk` (what a worker does with one chunk), :mod:`.executors` (this process, local
cores, a Dask cluster), :mod:`.results` (the table), :mod:`.runner` (the orchestration),
:mod:`.estimate` (time and disk before a run: ``estimate_campaign``), :mod:`.lab_export` (a
virtual campaign written as a lab's own export, to rehearse the evaluation of a lab's folder:
``write_lab_folder``).
"""
from droptower.campaign.lab_export import GERMAN, IMPERIAL, LabDialect, LabFolder, write_lab_folder
from droptower.campaign.runner import CampaignRun, estimate_campaign, run_campaign
from droptower.campaign.spec import CampaignSpec, prepare

__all__ = ["CampaignRun", "CampaignSpec", "estimate_campaign", "prepare", "run_campaign", "write_lab_folder", "LabFolder",
           "LabDialect", "GERMAN", "IMPERIAL"]
