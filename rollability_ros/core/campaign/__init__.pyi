"""The face of ``rollability_ros.core.campaign``: the names code outside the subpackage imports, and where each
lives. Type checkers read this stub; at run time ``lazy_loader.attach_stub`` (``__init__.py``) reads the same
imports and loads a name's module when the name is first used."""
from .adaptive import (DEFAULT_UNKNOWNS, TwinPredictor, Unknowns, WeightedPosterior, adaptive_next_trial,
                       budget_placeholders, candidate_conditions, proposal_lines)
from .calibration import (TWIN_CONFIGS, CalibrationResult, CalibrationSettings, LaunchPool, calibrate,
                          calibrated_parameter_document, calibration_settings, check_fittable, rig_parameter_document,
                          twin_settings_with)
from .characterisation import load_characterisation
from .learnt_plan import LearntTable, OutcomePosterior
from .likelihood import (OUTCOMES, ConditionLevels, LearntLikelihood, Observation, load_likelihood,
                         observations_from_outcomes, simulate_training_set, twin_fingerprint)
from .likelihood_gate import gate_term, shot_observations
from .likelihood_learning import learn
from .plan import CampaignSpec, load_campaign_spec, plan_trials, trial_id_for
from .posterior import (Posterior, characterisation_term, credible_set, format_set, sample_posterior,
                        temperature_statement)
from .sequential import comparison_stop_rule, paired_order
from .runner import (LocalRig, LocalRigSettings, RunnerSettings, StoreAcknowledgements, answer_rig, local_rig_settings,
                     local_rig_settings_from_files, plan_refusal, record_campaign_run, report_exit_code, resume_command,
                     resume_refusal, run_campaign, store_writer)
from .terminal import AnsweredElsewhere, TerminalAsk
from .twin_files import check_designs_print, load_twin_files
from .twin_record import RecordedTwin, recorded_twin

__all__ = [
    "DEFAULT_UNKNOWNS", "OUTCOMES", "TWIN_CONFIGS", "AnsweredElsewhere", "CalibrationResult", "CalibrationSettings",
    "CampaignSpec", "ConditionLevels", "LaunchPool", "LearntLikelihood", "LearntTable", "LocalRig", "LocalRigSettings",
    "Observation", "OutcomePosterior", "Posterior", "RecordedTwin", "RunnerSettings", "StoreAcknowledgements",
    "TerminalAsk", "TwinPredictor",
    "Unknowns", "WeightedPosterior", "adaptive_next_trial", "answer_rig", "budget_placeholders",
    "calibrate", "calibrated_parameter_document", "calibration_settings", "candidate_conditions",
    "characterisation_term", "check_designs_print", "check_fittable", "comparison_stop_rule", "credible_set",
    "format_set", "gate_term", "learn",
    "load_campaign_spec", "load_characterisation", "load_likelihood", "load_twin_files", "local_rig_settings",
    "local_rig_settings_from_files", "observations_from_outcomes", "paired_order", "plan_refusal", "plan_trials",
    "proposal_lines", "record_campaign_run", "recorded_twin", "report_exit_code", "resume_command", "resume_refusal",
    "rig_parameter_document", "run_campaign", "sample_posterior", "shot_observations", "simulate_training_set",
    "store_writer",
    "temperature_statement", "trial_id_for", "twin_fingerprint", "twin_settings_with"
]
