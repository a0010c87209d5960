"""The face of ``rollability_ros.core.results``: the names code outside the subpackage imports, and where each
lives. Type checkers read this stub; at run time ``lazy_loader.attach_stub`` (``__init__.py``) reads the same
imports and loads a name's module when the name is first used."""
from .analysis import ConditionResult, SimVsExperiment, convergence, group_conditions, sim_vs_experiment, summarise
from .engine_agreement import TABLE_FILENAME, summary_lines, table_rows, trial_agreement, write_table
from .outcome_log import OutcomeLog, OutcomeLoggerSettings, SessionGate, StoreFailure
from .report import directory_store, load_report_data, use_geometry_csv
from .report_writer import build_report, check_report_dir
from .report_figures import convergence_figure, sensitivity_figure
from .sensitivity_table import gain_lines
from ._outcome_csv import OutcomeCsvError, read_outcome_csv, write_outcome_csv

__all__ = [
    "TABLE_FILENAME", "ConditionResult", "OutcomeCsvError", "OutcomeLog", "OutcomeLoggerSettings", "SessionGate",
    "SimVsExperiment", "StoreFailure", "build_report", "check_report_dir", "convergence", "convergence_figure",
    "directory_store", "gain_lines", "group_conditions", "load_report_data", "read_outcome_csv", "sensitivity_figure",
    "sim_vs_experiment",
    "summarise", "summary_lines", "table_rows", "trial_agreement", "use_geometry_csv", "write_outcome_csv",
    "write_table"
]
