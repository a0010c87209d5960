"""How the cylinder drives the push plate (:mod:`rollability_ros.core.sim.launch`, "Launch"): the stroke model's
force and its speed solve, which launches the bare robot on the engine the settings name until the speed gate
reads the set speed (:func:`launch_drive`)."""
import dataclasses
import hashlib
import math
import pickle
import typing

from rollability_ros.core.profile import DesignSources
from rollability_ros.core.records import LaunchCondition
from rollability_ros.core.sim.launch.contract import LaunchDrive
from rollability_ros.core.sim.launch.placement import check_launcher
from rollability_ros.core.sim.launch.settings import (PA_PER_PSI, FoamSpec, LauncherSpec, LaunchTwinSettings,
                                                      mecanum_wheels)
from rollability_ros.core.sim.engines import LAUNCH_ENGINES
from rollability_ros.core.sim.launcher_geometry import robot_envelope
from rollability_ros.core.sim.trials import TrialSettings


#: The stroke model's speed solve: gate speed within this fraction of the set speed, at most this many runs
#: after the bracket.
SOLVE_TOLERANCE, SOLVE_RUNS = 0.002, 20

#: A gate reading that jumps across the set speed (the robot's contact with the plate or the ledge changes with the
#: plate speed: a taller robot pitches) has no setting within SOLVE_TOLERANCE; the closest setting tried is kept when
#: the gate reads within this fraction of the set speed, as a lab turning the regulator would keep it (well inside
#: the speed gate's own flag, config/rig.yaml ``speed_gate.tolerance_fraction`` 0.15).
SOLVE_ACCEPT_FRACTION = 0.05

#: Largest plate speed / set speed the solve tries before it refuses (the cylinder cannot reach the set speed).
SOLVE_MAX_RATIO = 4.0

#: Solved speed ratios per (engine, robot, launcher, set speed) in this process.
_SOLVED: typing.Dict[str, float] = {}

def cylinder_force_n(launcher: LauncherSpec, set_speed_mps: float) -> float:
    """The stroke cylinder's force (N) at the set speed's regulator pressure: pressure x bore area (``bore_m`` as
    sized for the robot, :func:`sized_for_robot`)."""
    return launcher.pressure_psi(set_speed_mps) * PA_PER_PSI * math.pi * (launcher.bore_m / 2) ** 2

def launch_drive(settings: LaunchTwinSettings, set_speed_mps: float) -> LaunchDrive:
    """The :class:`LaunchDrive` of launches at the set (nominal) speed ``set_speed_mps`` on the sized twin
    ``settings`` (:func:`sized_for_robot`).

    ``push_through``: the plate at the launch speed, ``plate.max_force_n``, ``plate.ramp_s``, until the robot goes
    over. ``stroke``: the cylinder pushes with :func:`cylinder_force_n` for ``launcher.stroke_m`` at the speed the
    lab's setting gives: as the lab sets the pressure until the speed gate reads the set speed over the run (paper
    2.2), the plate's speed is solved (once per engine, robot, launcher and set speed, cached) so that a launch of
    the bare robot square to the edge, without scatter, reads ``run_length_m / travel_time_s`` = the set speed
    within :data:`SOLVE_TOLERANCE`. ``ValueError`` when no plate speed up to :data:`SOLVE_MAX_RATIO` x the set
    speed gets there, naming the physical cause (:func:`why_not_launched`) and the settings."""
    plate, launcher = settings.twin.plate, settings.twin.launcher
    if launcher.model == "push_through":
        return LaunchDrive("push_through", 1.0, plate.max_force_n, math.inf, plate.ramp_s)
    force_n = cylinder_force_n(launcher, set_speed_mps)
    ramp_s = settings.physics.time_step_s   # a step: the force limit sets the acceleration
    canonical = dataclasses.replace(settings, trial=TrialSettings(), twin=dataclasses.replace(
        settings.twin, speed_sigma_fraction=0.0, angle_sigma_deg=0.0, designs=DesignSources(),
        foam=FoamSpec(), launcher=dataclasses.replace(launcher, speed_bias_fraction=0.0)))
    key = hashlib.sha256(pickle.dumps((canonical, float(set_speed_mps)), protocol=4)).hexdigest()
    if key not in _SOLVED:
        _SOLVED[key] = _solve_speed_ratio(settings, set_speed_mps, force_n, ramp_s)
        while len(_SOLVED) > 256:
            del _SOLVED[next(iter(_SOLVED))]
    return LaunchDrive("stroke", _SOLVED[key], force_n, launcher.stroke_m, ramp_s)

def _solve_speed_ratio(settings: LaunchTwinSettings, set_speed_mps: float, force_n: float, ramp_s: float) -> float:
    """The plate speed / set speed at which the gate reads the set speed (:func:`launch_drive`): secant steps from
    1 (the gate reads 0 at 0); when they do not converge, the ratio is raised by half until the gate reads at least
    the set speed (a launch that never reaches the edge reads 0) and the bracket is closed by regula falsi
    (Illinois). A reading that jumps across the set speed keeps the closest setting tried when it is within
    :data:`SOLVE_ACCEPT_FRACTION`; ``ValueError`` otherwise."""
    exact = dataclasses.replace(settings, twin=dataclasses.replace(
        settings.twin, speed_sigma_fraction=0.0, angle_sigma_deg=0.0,
        launcher=dataclasses.replace(settings.twin.launcher, speed_bias_fraction=0.0)))
    condition = LaunchCondition("baseline", 0.75, set_speed_mps, 0.0)   # the bare robot: profile None below
    engine = LAUNCH_ENGINES.get(settings.physics.engine)
    launcher = settings.twin.launcher

    closest: typing.List[typing.Tuple[float, float]] = []   # (|miss|, ratio) of the closest setting tried

    def miss(ratio: float) -> float:   # gate speed - set speed, m/s
        drive = LaunchDrive("stroke", ratio, force_n, launcher.stroke_m, ramp_s)
        gate = engine.simulate(condition, exact, 0, None, drive=drive, until_edge=True).measured_speed_mps
        off = (gate if gate > 0 else 0.0) - set_speed_mps
        closest[:] = [min([*closest, (abs(off), ratio)])]
        return off

    tolerance = SOLVE_TOLERANCE * set_speed_mps
    # the secant from the plate at the set speed: the gate's reading is nearly proportional for a free-rolling
    # robot (the chassis: 3 launches); the bracket below takes over when it is not
    ratio, ratio_miss = 1.0, miss(1.0)
    previous, previous_miss = 0.0, -set_speed_mps
    for _ in range(4):
        if abs(ratio_miss) <= tolerance:
            return ratio
        slope = (ratio_miss - previous_miss) / (ratio - previous)
        if not slope > 0:
            break
        previous, previous_miss = ratio, ratio_miss
        ratio = min(SOLVE_MAX_RATIO, max(0.5 * ratio, ratio - ratio_miss / slope))
        ratio_miss = miss(ratio)
    low, low_miss = 0.0, -set_speed_mps
    high, high_miss = 1.0, miss(1.0)
    while high_miss < -tolerance:
        low, low_miss = high, high_miss
        high *= 1.5
        if high > SOLVE_MAX_RATIO:
            strongest = LaunchDrive("stroke", low, force_n, launcher.stroke_m, ramp_s)
            raise ValueError(
                f"the stroke launcher cannot launch this robot at {set_speed_mps} m/s: with the plate at "
                f"{low * set_speed_mps:.2f} m/s and {force_n:.0f} N (launch_twin.launcher.pressures_psi "
                f"{launcher.pressure_psi(set_speed_mps):.0f} psi x bore {launcher.bore_m * 1000:.1f} mm) the gate "
                f"reads {set_speed_mps + low_miss:.3f} m/s: {why_not_launched(exact, strongest, set_speed_mps)}")
        high_miss = miss(high)
    side = 0
    for _ in range(SOLVE_RUNS):
        if abs(high_miss) <= tolerance:
            return high
        ratio = high - high_miss * (high - low) / (high_miss - low_miss)
        ratio_miss = miss(ratio)
        if abs(ratio_miss) <= tolerance:
            return ratio
        if ratio_miss > 0:
            high, high_miss = ratio, ratio_miss
            low_miss = low_miss / 2 if side == 1 else low_miss
            side = 1
        else:
            low, low_miss = ratio, ratio_miss
            high_miss = high_miss / 2 if side == -1 else high_miss
            side = -1
    if closest and closest[0][0] <= SOLVE_ACCEPT_FRACTION * set_speed_mps:   # the reading jumps: keep the closest
        return closest[0][1]
    raise ValueError(f"the stroke launcher's speed setting for {set_speed_mps} m/s did not converge in {SOLVE_RUNS} "
                     f"launches (the gate reads {set_speed_mps + high_miss:.3f} m/s at plate speed "
                     f"{high * set_speed_mps:.2f} m/s)")


#: A launch whose robot moved less than this fraction of the plate's stroke was not pushed through the stroke.
PUSHED_FRACTION = 0.8

def why_not_launched(settings: LaunchTwinSettings, drive: LaunchDrive, set_speed_mps: float) -> str:
    """Why the bare robot, launched square to the edge at the set speed ``set_speed_mps`` with ``drive`` on the sized
    twin ``settings`` (no scatter), does not reach the edge: one clause naming the physical cause and what changes
    it: a plate that misses it (:func:`check_launcher`), else from the poses of one more such launch.

    It tips over on the launcher (its up axis turns beyond the robot's ``upright_tilt_deg``, the rig's own "not
    upright", at most 90 deg): a property of the robot pushed at that height, not of the pressure; the plate does
    not push it through the stroke (it moved less than :data:`PUSHED_FRACTION` of it: the plate passed beneath it,
    slipped past or lifted it, or is too weak to move it at all); or it coasts to rest short of the edge after the
    stroke (the cylinder's push is too short or too weak for its rolling resistance)."""
    try:   # a plate that cannot meet the robot says so first (no launch needed)
        check_launcher(settings)
    except ValueError as exc:
        return str(exc)
    condition = LaunchCondition("baseline", 0.75, set_speed_mps, 0.0)
    poses: typing.List[typing.Tuple[typing.Sequence[float], typing.Sequence[float]]] = []
    LAUNCH_ENGINES.get(settings.physics.engine).simulate(
        condition, settings, 0, None, on_pose=lambda _t, position, orientation: poses.append((position, orientation)),
        drive=drive, until_edge=True)
    envelope = robot_envelope(settings.robot_model())
    plate, launcher = settings.twin.plate, settings.twin.launcher
    from scipy.spatial.transform import Rotation   # scipy: the sim extra's, like the engines

    start_rotation = Rotation.from_quat(poses[0][1]).as_matrix()   # (x, y, z, w), as the engines report it
    travel_m = float(poses[-1][0][0] - poses[0][0][0])
    tilts = []
    for _, orientation in poses:   # the body's turn from its start, in the world: its pitch and how far up tilts
        turn = Rotation.from_quat(orientation).as_matrix() @ start_rotation.T
        tilts.append((math.degrees(math.acos(max(-1.0, min(1.0, turn[2, 2])))),
                      math.degrees(math.asin(max(-1.0, min(1.0, -turn[2, 0]))))))
    tilt_deg, pitch_deg = max(tilts)
    push = (f"the plate's face {plate.clearance_m:.3f}-{plate.clearance_m + plate.height_m:.3f} m up, its centre "
            f"of mass {envelope.com_height_m:.3f} m up")
    if tilt_deg >= min(settings.robot_model().upright_tilt_deg, 90.0):
        way = ("nose-down" if pitch_deg > 0 else "tail-down") if abs(pitch_deg) >= tilt_deg / 2 else "sideways"
        return (f"it tips over on the launcher ({tilt_deg:.0f} deg, {way}) under the push ({push}), a property of "
                "the robot pushed there that no pressure changes; launch it with the plate at another height "
                "(launch_twin.plate.height_m, clearance_m) or not on this rig")
    stroke_m = min(drive.stroke_m, launcher.run_length_m)
    if travel_m < PUSHED_FRACTION * stroke_m:
        return (f"the plate does not push it through the stroke: it moves {travel_m:.3f} m of the plate's "
                f"{stroke_m} m and pitches {pitch_deg:+.0f} deg (+ = nose-down; {push}): the plate meets too little "
                f"of it (passes beneath, slips past or lifts it) or {drive.force_n:.0f} N cannot move it; set "
                "launch_twin.plate.height_m and clearance_m to meet its rear face squarely (0 = derived), or raise "
                "the pressure or the bore")
    wheels = ("launch_twin.wheel_rolling_friction, wheel_drag_torque_nm" if mecanum_wheels(settings) else
              "launch_twin.wheel_rolling_resistance, " +
              ("urdf_robot.joint_drag_torque_nm" if settings.urdf_robot.selected else "robot.wheel_drag_torque_nm"))
    return (f"it coasts to rest {max(0.0, launcher.run_length_m - travel_m):.3f} m short of the edge after the "
            f"{stroke_m} m stroke; raise the pressure or the bore, lower its wheels' resistance ({wheels}), or set "
            "launch_twin.launcher.model: push_through")
