"""The face of ``rollability_ros.core.campaign``: the names code outside the subpackage imports, and where each
lives. Type checkers read this stub; at run time ``lazy_loader.attach_stub`` (``__init__.py``) reads the same
imports and loads a name's module when the name is first used."""
from .adaptive import (DEFAULT_UNKNOWNS, TwinPredictor, Unknowns, WeightedPosterior, adaptive_next_trial,
                       budget_placeholders, candidate_conditions, proposal_lines)
from .calibration import (TWIN_CONFIGS, CalibrationResult, LaunchPool, calibrate, calibrated_parameter_document,
                          calibration_settings, check_fittable, rig_parameter_document, twin_settings_with)
from .characterisation import load_characterisation
from .plan import CampaignSpec, load_campaign_spec, plan_trials, trial_id_for
from .sequential import comparison_stop_rule, paired_order
from .runner import (LocalRig, LocalRigSettings, RunnerSettings, StoreAcknowledgements, answer_rig, local_rig_settings,
                     local_rig_settings_from_files, plan_refusal, record_campaign_run, report_exit_code, resume_command,
                     resume_refusal, run_campaign, store_writer)
from .terminal import AnsweredElsewhere, TerminalAsk

__all__ = [
    "DEFAULT_UNKNOWNS", "TWIN_CONFIGS", "AnsweredElsewhere", "CalibrationResult", "CampaignSpec", "LaunchPool", "LocalRig",
    "LocalRigSettings", "RunnerSettings", "StoreAcknowledgements", "TerminalAsk", "answer_rig", "calibrate",
    "calibrated_parameter_document", "calibration_settings", "check_fittable", "load_campaign_spec",
    "load_characterisation", "local_rig_settings", "local_rig_settings_from_files", "plan_refusal", "plan_trials",
    "record_campaign_run", "report_exit_code", "resume_command", "resume_refusal", "rig_parameter_document",
    "run_campaign", "store_writer", "trial_id_for", "twin_settings_with", "TwinPredictor", "Unknowns",
    "WeightedPosterior", "adaptive_next_trial", "budget_placeholders", "candidate_conditions", "comparison_stop_rule",
    "paired_order", "proposal_lines"
]
