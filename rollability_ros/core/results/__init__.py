"""Everything read from the durable store: the outcome log, CSV, analysis, figures, report.

The records, their message mapping, the store and the statistics are the core's shared bottom layer
(``rollability_ros.core.records``, ``record_messages``, ``store``, ``stats``); ``records``, ``record_messages``,
``store`` and ``stats`` here are their old paths, kept for code not yet moved.

- outcome_log: store-before-acknowledge bookkeeping of the outcome logger
- outcome_csv: strict CSV import/export of hand-recorded outcomes
- analysis, report, report_figures: the paper's views, figures and HTML report
- design_map: a quality-diversity run's map (archive.csv, traits.csv) and its height / sharpness trends
- engine_agreement: the same trials in two physics engines: trial and rank agreement, robust designs
"""
