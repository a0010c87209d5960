"""Optimization of profile heights: CMA-ES, the run loop with checkpoints, design selection.

- cmaes: ask / tell / stop / result around pycma
- optimization_run: generations through an injected evaluator, logged, checkpointed, resumable
- checkpoint: atomic checkpoints checked against the run's config
- evaluator_pool: a batch of evaluations spread over the available evaluators
- selection: designs A/B/C from a run's log
"""
