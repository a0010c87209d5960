"""The launch rig: one trial's sequence, the solenoid valve and its backends, the relay simulator, speed gates.

- launch_backend: the LaunchBackend contract (check, launch, close) and the RigPorts a caller provides
- rig_session: its two implementations (SimulatedLaunch, PhysicalLaunch), make_launch_backend; goal checks,
  phases, operator answers, IMU outcome, speed
- valve: fail-closed valve state machine
- valve_backends: dry-run, GPIO and serial relay backends
- relay_device_sim: a simulated relay board on a pseudo-terminal (own process)
- speed_gate: launch speed from light-gate travel times
"""
