"""The launch campaign: experiment matrix and order, the campaign loop, calibration of the twin.

- plan: experiment matrix, trial order, operator changes, resume, progress
- runner: the campaign loop over an injected launch and store acknowledgement
- terminal: the operator's prompt that another place (the rig CLI) can answer first
- twin_files: the twin's parameter files a user gives calibrate and the adaptive plan, and their designs' print
- twin_record: the simulated rig's twin files recorded in a campaign run's info, and checked for a re-simulation
- calibration: fit the launch twin's uncertain parameters to physical outcomes
- characterisation: bench readings taken before a campaign (docs/characterisation.md) and their likelihood
- likelihood: the twin's likelihood learnt once per robot and design set, its training launches and its file
- likelihood_learning: the likelihood's ensemble of networks learnt from the training launches (scikit-learn)
- gate_reading: the speed gate's reading in the twin and the Gaussian of a group of readings
- likelihood_gate: the speed gate's readings (and the launcher's gate shots) as an exact term of the calibration
- posterior: the posterior of a learnt likelihood's unknowns and its 95% sets
- adaptive: which launch next (BALD over weighted samples of the unknowns, behind an UprightPredictor protocol)
- learnt_plan: which launch next from a learnt likelihood, its verdicts and continuous outcomes
- sequential: the always-valid paired test that stops a design comparison once decided
- plan_comparison: the adaptive plan against the paper's matrix on simulated truths (bench_adaptive_plan)

The face is ``__init__.pyi`` beside this file: the names code outside ``core/campaign`` imports (``from
rollability_ros.core.campaign import <name>``), each with the module it lives in. ``lazy_loader.attach_stub``
(scientific-python SPEC 1) reads it: importing the face loads none of the modules behind it, and a name's
module is imported when the name is first used, so a light caller (the rig computer) never pays for numpy,
physics or plotting. Type checkers read the same stub. test/core/test_faces.py checks both.
"""
import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
