"""Physics (PyBullet; MuJoCo as an option): worlds, disturbance trials, fitness evaluation, the stable-pose screen,
the launch twin.

- world: PhysicsParams and one DIRECT client per simulation
- engines: the engine tables (TRIAL_ENGINES, LAUNCH_ENGINES) and the checks of sim.engine against them (the bottom)
- trial_engine: the TrialEngine contract, TrialOutcome and make_trial_world (builds the engine sim.engine names)
- _body_points: hull points, mass and centre of mass of a spawned PyBullet body's links
- trials: one disturbance trial (start, push, rest, upright test)
- pybullet_trials: TrialWorld, the pybullet engine
- mujoco_trials: the same trial in MuJoCo (sim.engine: mujoco)
- early_decision: ends a trial once energy fixes its outcome (barriers to the resting poses)
- evaluation: fitness = upright / trials, serial, process pool or Ray
- objectives: what a trial of a candidate is (disturbance, launch_twin, mix), the fidelities and their engines
- _worker_pool: spawned worker processes that never outlive their parent
- stable_poses: analytic stable-pose screen
- robustness, sensitivity, world_check: draws of the unknowns; one at a time; N fixed draws (plausible worlds)
- launcher_geometry: the launch twin's push plate and ledge sized from the robot's collision geometry (engine-free)
- rollout: the characterisation's roll-out (the bare robot pushed and let go on the foam or a plate) in the twin
- launch/: the simulated launch rig: settings, results, contract, placement, decision, loop, drive, twin (the entry)
  and one module per engine (pybullet_twin, mujoco_twin: the same rules in MuJoCo)

The face is ``__init__.pyi`` beside this file: the names code outside ``core/sim`` imports (``from
rollability_ros.core.sim import <name>``), each with the module it lives in. ``lazy_loader.attach_stub``
(scientific-python SPEC 1) reads it: importing the face loads none of the modules behind it, and a name's
module is imported when the name is first used, so a light caller (the rig computer) never pays for numpy,
physics or plotting. Type checkers read the same stub. test/core/test_faces.py checks both.
"""
import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
