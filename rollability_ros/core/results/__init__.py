"""Everything read from the durable store: the outcome log, CSV, analysis, figures, report.

The records, their message mapping, the store and the statistics are the core's shared bottom layer
(``rollability_ros.core.records``, ``record_messages``, ``store``, ``stats``).

- outcome_log: store-before-acknowledge bookkeeping of the outcome logger
- _outcome_csv: strict CSV import/export of hand-recorded outcomes
- analysis, report_figures: the paper's views and figures
- report: what a report says (records read, summary text); report_writer: its CSV, PNG and HTML files
- lead: the report's lead, which design to print first (the recommendation rule with the campaign's evidence)
- design_map: a quality-diversity run's map (archive.csv, traits.csv) and its height / sharpness trends
- engine_agreement: the same trials in two physics engines: trial and rank agreement, robust designs
- sensitivity_table: the sensitivity study as gains, each design minus the bare chassis per unknown factor

The face is ``__init__.pyi`` beside this file: the names code outside ``core/results`` imports (``from
rollability_ros.core.results import <name>``), each with the module it lives in. ``lazy_loader.attach_stub``
(scientific-python SPEC 1) reads it: importing the face loads none of the modules behind it, and a name's
module is imported when the name is first used, so a light caller (the rig computer) never pays for numpy,
physics or plotting. Type checkers read the same stub. test/core/test_faces.py checks both.
"""
import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
