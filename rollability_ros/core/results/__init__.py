"""Everything read from the durable store: the outcome log, CSV, analysis, figures, report.

The records, their message mapping, the store and the statistics are the core's shared bottom layer
(``rollability_ros.core.records``, ``record_messages``, ``store``, ``stats``); ``records``, ``record_messages``,
``store`` and ``stats`` here are their old paths, kept for code not yet moved.

- outcome_log: store-before-acknowledge bookkeeping of the outcome logger
- _outcome_csv: strict CSV import/export of hand-recorded outcomes
- analysis, report_figures: the paper's views and figures
- report: what a report says (records read, summary text); report_writer: its CSV, PNG and HTML files
- lead: the report's lead, which design to print first (the recommendation rule with the campaign's evidence)
- design_map: a quality-diversity run's map (archive.csv, traits.csv) and its height / sharpness trends
- engine_agreement: the same trials in two physics engines: trial and rank agreement, robust designs

The face below is what code outside ``core/results`` imports (``from rollability_ros.core.results import
OutcomeLog``). It is lazy (``core/faces.py``): importing it loads none of the modules behind it, and a name's module
is imported when the name is first used, so a light caller never pays for numpy and matplotlib.
"""
import typing

from rollability_ros.core.faces import lazy_attribute

if typing.TYPE_CHECKING:   # imported when first used: lazy_attribute reads this block
    from rollability_ros.core.results import (analysis, design_map, engine_agreement, lead, report, report_figures,
                                              report_writer)
    from rollability_ros.core.results.engine_agreement import trial_agreement
    from rollability_ros.core.results._outcome_csv import OutcomeCsvError, read_outcome_csv, write_outcome_csv
    from rollability_ros.core.results.outcome_log import OutcomeLog, OutcomeLoggerSettings, SessionGate, StoreFailure
    from rollability_ros.core.results.report import load_report_data
    from rollability_ros.core.results.sensitivity_table import gain_lines

__all__ = [
    "OutcomeCsvError", "OutcomeLog", "OutcomeLoggerSettings", "SessionGate", "StoreFailure", "analysis", "design_map",
    "engine_agreement", "gain_lines", "lead", "load_report_data", "read_outcome_csv", "report", "report_figures",
    "report_writer", "trial_agreement", "write_outcome_csv",
]


def __getattr__(name: str) -> typing.Any:
    return lazy_attribute(__name__, name)
