"""The launch campaign: experiment matrix and order, the campaign loop, calibration of the twin.

- plan: experiment matrix, trial order, operator changes, resume, progress
- runner: the campaign loop over an injected launch and store acknowledgement
- terminal: the operator's prompt that another place (the rig CLI) can answer first
- calibration: fit the launch twin's uncertain parameters to physical outcomes
- characterisation: bench readings taken before a campaign (docs/characterisation.md) and their likelihood
- likelihood: the twin's likelihood learnt once per robot and design set, its file, the posterior and its sets

The face below is what code outside ``core/campaign`` imports. ``calibration``, ``characterisation`` and
``likelihood`` are public as modules and are not imported here (they load numpy and the twin), so the rig
computer's campaign runner stays light.
"""
from rollability_ros.core.campaign.plan import CampaignSpec, load_campaign_spec, plan_trials, trial_id_for
from rollability_ros.core.campaign.runner import (LocalRig, LocalRigSettings, RunnerSettings, StoreAcknowledgements,
                                                  answer_rig, local_rig_settings, local_rig_settings_from_files,
                                                  plan_refusal, record_campaign_run, report_exit_code, resume_command,
                                                  resume_refusal, run_campaign, store_writer)
from rollability_ros.core.campaign.terminal import AnsweredElsewhere, TerminalAsk

__all__ = [
    "AnsweredElsewhere", "TerminalAsk",
    "CampaignSpec", "LocalRig", "LocalRigSettings", "RunnerSettings", "StoreAcknowledgements", "answer_rig",
    "calibration", "characterisation", "likelihood", "load_campaign_spec", "local_rig_settings", "local_rig_settings_from_files", "plan_refusal",
    "plan_trials", "record_campaign_run", "report_exit_code", "resume_command", "resume_refusal", "run_campaign", "store_writer",
    "trial_id_for",
]
