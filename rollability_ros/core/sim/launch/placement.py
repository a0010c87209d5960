"""Engine-neutral geometry and draws of one launch (:mod:`rollability_ros.core.sim.launch`, "Launcher sized for the
robot", "Angle", "Launch"): the launcher sized for the robot, where the robot and the plate start, and the seeded
scatter of speed and angle. Every engine's twin places its bodies by these rules."""
import dataclasses
import math
import typing

import numpy as np
import numpy.typing as npt

from rollability_ros.core.records import LaunchCondition
from rollability_ros.core.sim.launch.settings import LauncherSpec, LaunchTwinOptions, LaunchTwinSettings, PushPlateSpec
from rollability_ros.core.sim.launcher_geometry import (LauncherGeometry, RobotEnvelope, check_launcher_geometry,
                                                         derive_launcher_geometry, robot_envelope)


#: Smallest cosine between the push and the edge normal (``yaw_of_push`` angles up to about +-84 deg).
MIN_PUSH_TOWARDS_EDGE = 0.1

def sized_for_robot(settings: LaunchTwinSettings
                    ) -> typing.Tuple[LaunchTwinSettings, RobotEnvelope, LauncherGeometry]:
    """``(settings, envelope, geometry)``: ``settings`` with the launcher's robot-dependent sizes that are 0 in the
    config (plate width, height and clearance; ledge depth and width) derived from the robot's collision geometry
    (:mod:`~rollability_ros.core.sim.launcher_geometry`), the robot's
    :class:`~rollability_ros.core.sim.launcher_geometry.RobotEnvelope` and the
    :class:`~rollability_ros.core.sim.launcher_geometry.LauncherGeometry` used."""
    launcher, plate = settings.twin.launcher, settings.twin.plate
    envelope = robot_envelope(settings.robot_model())
    geometry = derive_launcher_geometry(envelope, launcher.run_length_m, plate.thickness_m, {
        "plate_width_m": plate.width_m, "plate_height_m": plate.height_m, "plate_clearance_m": plate.clearance_m,
        "plate_max_force_n": plate.max_force_n, "ledge_depth_m": launcher.ledge_depth_m, "ledge_width_m": launcher.ledge_width_m,
        "cylinder_bore_m": launcher.bore_m}, plate.offset_m)
    twin = dataclasses.replace(
        settings.twin,
        launcher=dataclasses.replace(launcher, ledge_depth_m=geometry.ledge_depth_m,
                                     ledge_width_m=geometry.ledge_width_m, bore_m=geometry.cylinder_bore_m),
        plate=dataclasses.replace(plate, width_m=geometry.plate_width_m, height_m=geometry.plate_height_m,
                                  clearance_m=geometry.plate_clearance_m, max_force_n=geometry.plate_max_force_n))
    return dataclasses.replace(settings, twin=twin), envelope, geometry

def check_launcher(settings: LaunchTwinSettings) -> LauncherGeometry:
    """Check before a campaign that the (derived or configured) launcher launches this robot: the push plate meets
    its collision shapes and it fits on the ledge; ``ValueError`` naming the setting. Returns the
    :class:`~rollability_ros.core.sim.launcher_geometry.LauncherGeometry`."""
    _, envelope, geometry = sized_for_robot(settings)
    check_launcher_geometry(envelope, geometry, settings.twin.launcher.run_length_m, settings.twin.plate.offset_m)
    return geometry

def launcher_start_xy(lead_m: float, push: npt.ArrayLike, launcher: LauncherSpec) -> typing.Tuple[float, float]:
    """Where the base origin starts (x, y; m): its foremost point, ``lead_m`` ahead of it along x, reaches the edge
    after ``run_length_m`` along ``push`` (unit (3,)), on a path through the edge's midpoint (every twin's rule)."""
    push = np.asarray(push, dtype=np.float64)
    start = -(launcher.run_length_m + lead_m / push[0]) * push
    return float(start[0]), float(start[1])

def check_fits_launcher(low: typing.Sequence[float], high: typing.Sequence[float], launcher: LauncherSpec) -> None:
    """``ValueError`` when a robot whose world bounding box is ``low`` .. ``high`` (m) at its start is not wholly
    over the ledge (``ledge_depth_m`` behind the edge, ``ledge_width_m`` along it); ``low`` and ``high`` (3,)."""
    side_m = max(-low[1], high[1])
    if low[0] < -launcher.ledge_depth_m or side_m > launcher.ledge_width_m / 2:
        raise ValueError(f"the robot does not fit on the launcher: placed {launcher.run_length_m} m before the edge "
                         f"it reaches {-low[0]:.3f} m behind the edge and {side_m:.3f} m to the side; the ledge is "
                         f"launch_twin.launcher.ledge_depth_m = {launcher.ledge_depth_m} m deep and "
                         f"ledge_width_m = {launcher.ledge_width_m} m wide")

@dataclasses.dataclass(frozen=True)
class PlatePlacement:
    """Where the push plate starts (every twin's rule, package docstring "Launch"): its base ``centre_m`` (3,),
    turned by ``yaw_rad`` (the push direction) with its face turned a further ``bias_rad``; ``face_x_m`` is the x
    of the face's leading point at zero travel."""

    centre_m: np.ndarray
    yaw_rad: float
    bias_rad: float
    face_x_m: float

def plate_placement(rear_m: float, base_m: npt.ArrayLike, push: npt.ArrayLike, spec: PushPlateSpec,
                    plate_z: float) -> PlatePlacement:
    """The :class:`PlatePlacement` behind a robot whose rearmost point lies ``rear_m`` along ``push`` (unit (3,))
    with its base origin at ``base_m`` (3,): the face 1 mm behind that point (a turned face leads with one corner),
    ``offset_m`` to the side of the base's path, its bottom ``clearance_m`` above the plate at ``plate_z``."""
    push = np.asarray(push, dtype=np.float64)
    lateral = np.array([-push[1], push[0], 0.0])
    bias = math.radians(spec.yaw_bias_deg)
    reach_m = spec.thickness_m / 2 * math.cos(bias) + spec.width_m / 2 * abs(math.sin(bias))
    along_m = rear_m - reach_m - 0.001
    centre = along_m * push + (float(np.asarray(base_m, dtype=np.float64) @ lateral) + spec.offset_m) * lateral
    centre[2] = plate_z + spec.clearance_m + spec.height_m / 2
    return PlatePlacement(centre_m=centre, yaw_rad=math.atan2(push[1], push[0]), bias_rad=bias,
                          face_x_m=(along_m + reach_m) * push[0])

def launch_draws(seed: int, nominal_speed_mps: float, nominal_angle_deg: float,
                 options: LaunchTwinOptions) -> typing.Tuple[float, float]:
    """The seeded scatter of one launch: ``(actual launch speed m/s, actual angle deg)``; the speed also carries
    the lab's systematic setting error ``launcher.speed_bias_fraction``."""
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
    rng = np.random.default_rng(int(seed))
    speed_factor, angle_offset = rng.standard_normal(2)
    speed = nominal_speed_mps * (1.0 + options.launcher.speed_bias_fraction) * max(
        0.05, 1.0 + options.speed_sigma_fraction * float(speed_factor))
    return speed, nominal_angle_deg + options.angle_sigma_deg * float(angle_offset)

def launch_plan(condition: LaunchCondition, seed: int,
                options: LaunchTwinOptions) -> typing.Tuple[float, float, np.ndarray]:
    """The drawn ``(launch speed m/s, angle deg, push direction (3,))`` of a launch of ``condition`` with ``seed``
    (package docstring, "Angle" and "Launch"); ``ValueError`` for an angle that pushes along or away from the edge."""
    speed_mps, angle_deg = launch_draws(seed, condition.speed_mps, condition.angle_deg, options)
    push_yaw = math.radians(angle_deg) if options.angle_convention == "yaw_of_push" else 0.0
    push = np.array([math.cos(push_yaw), math.sin(push_yaw), 0.0])
    if push[0] < MIN_PUSH_TOWARDS_EDGE:
        raise ValueError(f"angle {angle_deg:.1f} deg pushes along or away from the edge under {options.angle_convention}"
                         f" (|angle| must stay below {math.degrees(math.acos(MIN_PUSH_TOWARDS_EDGE)):.0f} deg)")
    return speed_mps, angle_deg, push

def attempt_seed(seed: int, attempt: int) -> int:
    """The seed of retry ``attempt`` (0 = the launch's own ``seed``) of :func:`simulate_valid_launch`."""
    if attempt == 0:
        return int(seed)
    state = np.random.SeedSequence(int(seed), spawn_key=(0x1A7, int(attempt))).generate_state(1, dtype=np.uint32)
    return int(state[0]) & 0x7FFFFFFF
