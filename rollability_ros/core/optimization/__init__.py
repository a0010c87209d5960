"""Optimization of profile heights: CMA-ES or CMA-MAE, the run loop with checkpoints, design selection.

- optimizer_contract: the method contract (IncumbentOptimizer), its OPTIMIZER_METHODS table and the run's typed
  settings it is written in (RunSettings: OptimizerSettings, QualityDiversitySettings, ...)
- cmaes: the paper's method, ask / tell / stop / result around pycma
- quality_diversity: CMA-MAE (pyribs) filling a maximum height x sharpness archive
- optimization_run: generations through an injected evaluator, logged, checkpointed, resumable
- run_directory: a run's folder, its config.yaml and the parameter files it is loaded from
- batch_evaluation: the in-process evaluators a run is handed (evaluate_profile on a trial executor)
- checkpoint: atomic checkpoints checked against the run's config
- evaluator_pool: a batch of evaluations spread over the available evaluators
- racing: successive halving over common seeds, for the selection's race and the optimizer's sequential rule
- selection: deciding designs A/B/C from a run's log or its archive, and the world check behind the recommendation
- labelling: the labels A, B, C in the order the evidence after the pick ranks the chosen designs
- recommendation: the rule naming the design to print first from the plausible-world check
- design_set: writing a selection (STL, 3MF, Table 3, designs.yaml, the world check's rows) and its record

The face is ``__init__.pyi`` beside this file: the names code outside ``core/optimization`` imports (``from
rollability_ros.core.optimization import <name>``), each with the module it lives in. ``lazy_loader.attach_stub``
(scientific-python SPEC 1) reads it: importing the face loads none of the modules behind it, and a name's
module is imported when the name is first used, so a light caller (the rig computer) never pays for numpy,
physics or plotting. Type checkers read the same stub. test/core/test_faces.py checks both.
"""
import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
