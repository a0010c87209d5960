"""Optimization of profile heights: CMA-ES or CMA-MAE, the run loop with checkpoints, design selection.

- cmaes: ask / tell / stop / result around pycma
- quality_diversity: CMA-MAE (pyribs) filling a maximum height x sharpness archive
- optimization_run: generations through an injected evaluator, logged, checkpointed, resumable
- checkpoint: atomic checkpoints checked against the run's config
- evaluator_pool: a batch of evaluations spread over the available evaluators
- selection: designs A/B/C from a run's log or its archive

The face is ``__init__.pyi`` beside this file: the names code outside ``core/optimization`` imports (``from
rollability_ros.core.optimization import <name>``), each with the module it lives in. ``lazy_loader.attach_stub``
(scientific-python SPEC 1) reads it: importing the face loads none of the modules behind it, and a name's
module is imported when the name is first used, so a light caller (the rig computer) never pays for numpy,
physics or plotting. Type checkers read the same stub. test/core/test_faces.py checks both.
"""
import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
