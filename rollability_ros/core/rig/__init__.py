"""The launch rig: one trial's sequence, the solenoid valve and its backends, the relay simulator, speed gates.

- launch_backend: the LaunchBackend contract (check, launch, close), the RigPorts a caller provides, and the types
  it is written in (RigSettings, the operator channel and its answers, the LAUNCH_BACKENDS table)
- rig_session: its two implementations (SimulatedLaunch, PhysicalLaunch), make_launch_backend; goal checks,
  phases, operator answers, speed
- launched_twin: the twin files a rig launches in, as a run's info records them (re-simulation) and the rig node
  sends them to the outcome_logger
- outcome_sources: the IMU's verdict and continuous outcomes (ImuOutcome), the operator's distance rolled, the
  twin's continuous outcomes
- valve: fail-closed valve state machine
- valve_contract: the ValveBackend contract, its VALVE_BACKENDS table, make_valve_backend and ValveConfig
- valve_boards: the boards: dry-run, GPIO and serial relay backends
- relay_protocol: the relay board's serial protocol (RVR1) and its state machine (firmware/ mirrors it)
- gpio_line_holder: the tiny process that owns the gpio backend's line and speaks the board protocol on its pipes
- relay_device_sim: a simulated relay board on a pseudo-terminal (own process), running that state machine
- valve_auth: the per-session arming key and the signed valve requests (only the operator side fires)
- rig_auth: the same key signs the rig's launch goals, confirmations, operator outcomes and physical records
- rig_network: the physical rig's default ROS domain / discovery range and exposure warnings
- speed_gate: launch speed from light-gate travel times; the SpeedGate contract, SPEED_GATES and make_speed_gate

The face is ``__init__.pyi`` beside this file: the names code outside ``core/rig`` imports (``from
rollability_ros.core.rig import <name>``), each with the module it lives in. ``lazy_loader.attach_stub``
(scientific-python SPEC 1) reads it: importing the face loads none of the modules behind it, and a name's
module is imported when the name is first used, so a light caller (the rig computer) never pays for numpy,
physics or plotting. Type checkers read the same stub. test/core/test_faces.py checks both.
"""
import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
