"""The launch rig: one trial's sequence, the solenoid valve and its backends, the relay simulator, speed gates.

- launch_backend: the LaunchBackend contract (check, launch, close) and the RigPorts a caller provides
- rig_session: its two implementations (SimulatedLaunch, PhysicalLaunch), make_launch_backend; goal checks,
  phases, operator answers, IMU outcome, speed
- valve: fail-closed valve state machine
- _valve_backend: the ValveBackend contract, its VALVE_BACKENDS table and make_valve_backend
- valve_backends: dry-run, GPIO and serial relay backends
- relay_protocol: the relay board's serial protocol (RVR1) and its state machine (firmware/ mirrors it)
- gpio_line_holder: the tiny process that owns the gpio backend's line and speaks the board protocol on its pipes
- relay_device_sim: a simulated relay board on a pseudo-terminal (own process), running that state machine
- valve_auth: the per-session arming key and the signed valve requests (only the operator side fires)
- rig_network: the physical rig's default ROS domain / discovery range and exposure warnings
- speed_gate: launch speed from light-gate travel times; the SpeedGate contract, SPEED_GATES and make_speed_gate

The face below is what code outside ``core/rig`` imports (``from rollability_ros.core.rig import ValveConfig``);
the modules behind it may move. ``rig_auth`` and ``valve_auth`` are public as modules (the signed-request
protocol). Every module here is light (no numpy, no physics): importing the face loads no heavy dependency.
"""
from rollability_ros.core.rig import rig_auth, valve_auth
from rollability_ros.core.rig.launch_backend import LaunchAborted, LaunchBackend, RigPorts
from rollability_ros.core.rig.rig_network import (DISCOVERY_RANGES, RIG_DOMAIN_ID, check_domain_id, check_namespace,
                                                  exposure_warnings, physical_rig_environment)
from rollability_ros.core.rig.rig_session import (ANSWERED, ASK_OUTCOME, ASK_REGULATOR, LAUNCH_BACKENDS, ImuOutcome,
                                                  OperatorOutcome, PhysicalLaunch, RigSettings, SimulatedLaunch,
                                                  check_rest_distance, describe_answer, launch_backend_class,
                                                  make_launch_backend, parse_outcome_answer,
                                                  simulated_continuous_outcomes)
from rollability_ros.core.rig.speed_gate import SPEED_GATES, SpeedGate, SpeedGateConfig, make_speed_gate
from rollability_ros.core.rig.valve import ValveConfig, ValveController, ValveStatus
from rollability_ros.core.rig._valve_backend import (VALVE_BACKENDS, ValveBackend, make_valve_backend,
                                                     register_valve_backend)
from rollability_ros.core.rig.valve_backends import make_controller

__all__ = [
    "ANSWERED", "ASK_OUTCOME", "ASK_REGULATOR", "DISCOVERY_RANGES", "LAUNCH_BACKENDS", "RIG_DOMAIN_ID", "SPEED_GATES",
    "VALVE_BACKENDS",
    "ImuOutcome", "LaunchAborted", "LaunchBackend", "OperatorOutcome", "PhysicalLaunch", "RigPorts", "RigSettings",
    "SimulatedLaunch", "SpeedGate", "SpeedGateConfig", "ValveBackend", "ValveConfig", "ValveController",
    "ValveStatus", "check_domain_id", "check_namespace", "check_rest_distance", "describe_answer",
    "exposure_warnings", "launch_backend_class", "make_controller",
    "make_launch_backend", "make_speed_gate", "make_valve_backend", "parse_outcome_answer", "physical_rig_environment",
    "register_valve_backend", "simulated_continuous_outcomes", "rig_auth", "valve_auth",
]
