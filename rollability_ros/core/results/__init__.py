"""Records, the durable store, and everything read from it: analysis, figures, report, statistics.

- records: plain records exchanged between core, store, bags and nodes, each with validate()
- record_messages: the one record <-> ROS message mapping (rclpy in nodes/_convert, rosbags in bags/messages)
- store: SQLite (WAL) store of outcomes, candidates, generations, tip events
- outcome_log: store-before-acknowledge bookkeeping of the outcome logger
- outcome_csv: strict CSV import/export of hand-recorded outcomes
- analysis, report, report_figures: the paper's views, figures and HTML report
- stats: binomial intervals, rank correlation with a permutation test
- design_map: a quality-diversity run's map (archive.csv, traits.csv) and its height / sharpness trends
- engine_agreement: the same trials in two physics engines: trial and rank agreement, robust designs
"""
