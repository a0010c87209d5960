"""Optimization of profile heights: CMA-ES or CMA-MAE, the run loop with checkpoints, design selection.

- cmaes: ask / tell / stop / result around pycma
- quality_diversity: CMA-MAE (pyribs) filling a maximum height x sharpness archive
- optimization_run: generations through an injected evaluator, logged, checkpointed, resumable
- checkpoint: atomic checkpoints checked against the run's config
- evaluator_pool: a batch of evaluations spread over the available evaluators
- selection: designs A/B/C from a run's log or its archive
"""
