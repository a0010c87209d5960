"""The simulated launch twin (paper 2.2): the chassis pushed off the launcher's ledge onto memory foam, classified.

World (metres, world frame z up; one fresh PyBullet DIRECT world per launch, so a launch depends only on its
condition, seed and settings)
    - the floor: the plane of :func:`~rollability_ros.core.sim.world.reset_world` at z = 0;
    - the foam: a static box ``foam.length_m`` x ``foam.width_m`` x ``foam.thickness_m`` lying on the floor in
      front of the ledge (x from 0 to ``length_m``, centred on y = 0); its top, z = ``thickness_m``, is the
      impact surface;
    - the ledge: the launcher's base plate on its table, one static box behind the edge (x from
      ``-ledge_depth_m`` to 0, ``ledge_width_m`` along y) from the floor to ``height_m`` above the impact
      surface. The edge is the line x = 0 on its top; its outward normal is +x.
Contact
    The ledge gets the ground contact of ``config/sim.yaml`` (``PhysicsParams.ground_contact``) and the chassis
    its body contact, as in the trials. The foam gets ``foam.lateral_friction``, ``foam.rolling_friction`` and
    ``foam.restitution`` as its own body coefficients (Bullet multiplies them with the chassis's: with the
    chassis's 0.35 and 0.3, foam 1.0 and 0.1 give a contact friction of 0.35 and restitution 0.03; a wheel rolling
    on the foam meets ``wheel_rolling_friction`` + 0.35 x ``foam.rolling_friction``) and is compliant: Bullet's contact stiffness
    and damping (``contact_stiffness_npm``, ``contact_damping_nspm``), which Bullet combines with the chassis's
    defaults (stiffness infinite, damping 0.1 N s/m) to almost exactly the foam's values. They act per contact
    point, and a face landing flat makes up to four, so read them as the stiffness of one wheel or corner
    pressing into the foam.
Robot
    The built-in chassis, or any wheeled URDF robot when ``urdf_robot`` names a mount link (the trials' choice,
    :class:`~rollability_ros.core.robots.urdf_robot.RobotChoice`; e.g. ``config/husky.yaml`` in the twin's files).
    The profile weighs what that robot's ``profile_print`` makes of its mesh, times ``profile_mass_scale``.
Launcher sized for the robot (:mod:`~rollability_ros.core.sim.launcher_geometry`)
    The push plate's width, height, clearance and force and the ledge's depth and width are derived from the robot's
    collision geometry wherever the config leaves them 0 (the shipped ``config/launch_twin.yaml`` does; the
    built-in chassis gets the paper rig's 0.10 x 0.05 m plate 5 mm up, 200 N, and a 0.8 m ledge): the plate's face is
    centred on the height of the robot's centre of mass. :func:`check_launcher` (run by the rig's sim backend
    before a campaign) refuses a plate that would pass beneath or beside the robot and a ledge it does not fit
    on, naming the setting; a robot that does not fit on the ledge at its start (a turned start beyond the
    derived +-60 deg) is refused with a ``ValueError`` naming ``ledge_depth_m`` / ``ledge_width_m``.
Wheels (``wheel_model``: whose wheel contact and drag the twin uses)
    ``robot`` (``auto`` on a URDF robot): the robot's own, exactly as in the disturbance trials: its joint drag
    (``urdf_robot.joint_drag_torque_nm``) and the body contact of ``config/sim.yaml`` on every link, so a robot
    that lands level on its wheels stays where it landed. ``mecanum`` (``auto`` on the built-in chassis): the
    paper's chassis runs on Mecanum wheels, whose rollers let a wheel slide along its axle: the twin scales the
    wheels' friction along the axle by ``wheel_side_friction_factor`` (Bullet's anisotropic friction); rolling
    on the plate, a wheel resists with ``wheel_rolling_friction`` (Bullet rolling friction, a length in metres:
    the resisting force is about ``wheel_rolling_friction / wheel_radius_m`` times the load) and its motor
    back-drives against ``wheel_drag_torque_nm``. These replace the trial chassis's values on the wheel links
    because the trials model a generic geared wheel: with the trials' rolling friction 0.01 (a resisting force
    of a third of the load on a 0.03 m wheel) and drag 0.02 N m, the chassis stops within 0.1 m and never covers
    the paper's 0.34 m run at 0.8 m/s in 0.42 s. Either way ``wheel_friction_left_factor`` /
    ``wheel_friction_right_factor`` scale the wheels' friction (rig asymmetry, see below).
Angle (the paper gives mounting holes at -60 ... +60 deg, not a definition)
    Positive angles turn counterclockwise seen from above (about world +z), as in ``config/rig.yaml``.
    ``yaw_of_push`` (default): the push plate, and the chassis placed square against it, are turned by the angle
    from the edge's outward normal; the chassis runs ``run_length_m`` along the push direction and leaves the
    edge obliquely. ``chassis_yaw``: the push stays along the edge normal and only the chassis is turned on the
    plate (it runs sideways on its Mecanum rollers).
Launch (``launcher.model``; one setting swaps the two, and a setting of the model not chosen is refused)
    The push plate is a box (``launch_twin.plate``) on a prismatic joint along the push, velocity-controlled with a
    force limit; at t = 0 the chassis stands at rest on the launcher, the plate 1 mm behind it. ``stroke`` (default,
    the paper's rig, section 2.2): a 25 mm bore x 150 mm stroke cylinder at the regulator's 30 / 60 psi for the set
    speeds 0.8 / 1.5 m/s (``launcher.bore_m``, ``stroke_m``, ``pressures_psi``) drives the plate (with the piston
    and rod: ``plate.mass_kg``) with at most pressure x bore area (101 N / 203 N) up to the speed the lab's
    setting gives, for ``stroke_m`` of travel, then stops it; the chassis coasts on its wheels over the rest of
    the run (its wheels' rolling resistance, plus ``launcher.ledge_rolling_friction``, an unknown). The speed:
    the lab sets the pressure until the speed gate reads the set speed over ``run_length_m`` (0.42 s / 0.22 s
    over 0.34 m); pressure x bore gives 72 m/s^2 on the chassis, far more than those speeds need over 0.15 m, so
    the cylinder's speed is the exhaust flow's, not the force's. The twin models exactly that check: the plate's
    speed is solved per engine, robot, launcher and set speed (:func:`launch_drive`, cached) so that a launch of
    the bare robot square to the edge reads the set speed on the gate, within 0.2% (test_launch_twin: both
    engines, both speeds, within the gate's 15% tolerance ``speed_gate.tolerance_fraction``). A profile's mass
    then changes the gate's reading as physics says. A cylinder too weak to reach the set speed is refused with a
    ``ValueError`` naming the settings. ``push_through`` (the twin before issue 40): the plate's speed ramps to the
    launch speed in ``plate.ramp_s`` with at most ``plate.max_force_n`` and holds it until the chassis's base
    origin goes over the edge (or the plate's face reaches it), then brakes: the chassis leaves the edge at the
    launch speed (``edge_speed_mps``, within 5% on the shipped chassis and on one with 40 times the drag: see
    test_launch_twin). Either way the speed gate reads ``run_length_m / travel_time_s`` as on the rig. The chassis
    starts where its foremost point (largest x of its links' bounding boxes) reaches the edge line after
    ``run_length_m`` along the push, its base origin on a path through the edge's midpoint. The actual launch
    speed (the gate speed the setting gives in this launch) scatters around the condition's speed x (1 +
    ``launcher.speed_bias_fraction``, the setting's systematic error, an unknown) with a relative standard
    deviation ``speed_sigma_fraction``, and the angle by ``angle_sigma_deg`` (hand placement against the push
    plate), both drawn from the seed; the stroke's plate speed scales with it.
Asymmetry (the paper's rig is not mirror-symmetric in the angle; these let calibration fit it)
    ``plate.offset_m`` moves the plate sideways off the chassis's path, ``plate.yaw_bias_deg`` turns its face
    from square to the push (it then pushes on one corner), and ``wheel_friction_left_factor`` /
    ``wheel_friction_right_factor`` scale the friction of the wheels on the chassis's left (+y of its base) and
    right.
Invalid launches
    A launch in which the chassis does not leave the ledge, or whose first landing is not on the foam, did not
    happen as the rig launches: ``LaunchResult.invalid_reason`` says why. :func:`simulate_valid_launch` retries
    it with derived seeds up to ``max_attempts`` launches in all; the rig stores one still invalid as an invalid
    launch (:data:`~rollability_ros.core.records.INVALID_LAUNCH`), which the analysis leaves out.
Measurements and phases
    ``travel_time_s`` = time at which the foremost point crosses the edge line x = 0 (interpolated within the
    step): the light gates of the real rig, at the start and across the edge; ``measured_speed_mps`` =
    ``run_length_m / travel_time_s``. ``flight_time_s`` runs from the base origin crossing the edge line (the
    chassis goes over) to the first foam contact. Phases: ``fired`` at t = 0, ``in_flight`` when the base origin
    crosses the edge, ``settling`` at the first foam contact, ``classifying`` once the chassis has come to rest
    (the trials' rest detection, ``config/sim.yaml`` section ``trial``: speeds below thresholds for
    ``rest_hold_s``) or at the trials' time cap. Every phase is reported once, in this order, even when an event
    did not happen (a chassis too slow to leave the plate).
Outcome (the rig's rule, :func:`rig_verdict`; the same in every engine)
    Upright = at rest (the trials' rest rule, or the time cap) with the body's up axis within the robot's
    ``upright_tilt_deg`` of world up (30 deg, ``config/robot.yaml``: the rig's IMU classifier's
    ``imu_outcome.tilt_threshold_deg`` in ``config/rig.yaml``) and on its wheels (``min_wheels_in_contact`` wheels
    within ``contact_tolerance_m`` of the surface it rests on), wherever it rests: on the foam pad, on the floor
    beyond it, against the ledge. Where it came to rest (``rest_surface``, ``rest_position_m``,
    ``rest_distance_m``), ``time_to_rest_s``, its tilt and the peak deceleration are recorded beside the verdict
    and never decide it (test_launch_twin: a chassis that rolls off a 0.5 m pad and stops on its wheels on the
    floor is upright, both engines; test_launch_twin_outcome: the rule against the IMU classifier on analytic
    poses; measured, not tested: the same launches give upright counts within 3 of 100 on a 2.5 x 3 m pad and a
    30 x 30 m one, bench/bench_pad_size.py). The early decision (:func:`step_launch`) decides only while the robot cannot
    reach the pad's edges or the ledge, where the pad's top is the only ground and this rule is the one its
    energy barriers classify by.
"""
import dataclasses
import hashlib
import math
import os
import pickle
import types
import typing

import numpy as np
import numpy.typing as npt

from rollability_ros.core.config import ConfigError, from_mapping, load_parameters, resolve_config_path, section
from rollability_ros.core.profile import DesignSources, profile_mesh_for
from rollability_ros.core.optional import require
from rollability_ros.core.records import NO_SEED, NOT_MEASURED, LaunchCondition
from rollability_ros.core.robots import (ChassisSpec, ProfileBody, RobotChoice, RobotModel, SpawnedRobot,
                                        UrdfRobotSpec)
from rollability_ros.core.sim.launcher_geometry import (LauncherGeometry, RobotEnvelope, check_launcher_geometry,
                                                         derive_launcher_geometry, robot_envelope)
from rollability_ros.core.sim.world import PhysicsParams, connect, disconnect, reset_world, set_contact
from rollability_ros.core.sim.trial_engine import LAUNCH_ENGINES, LaunchEngine, check_engine
from rollability_ros.core.sim.trials import EnergyMonitor, RestDetector, TrialSettings, place_on_ground

#: ``launch_twin.angle_convention`` values (see the module docstring).
ANGLE_CONVENTIONS = ("yaw_of_push", "chassis_yaw")
#: ``launch_twin.wheel_model`` values: whose wheel contact and drag the twin uses (module docstring, "Wheels").
WHEEL_MODELS = ("auto", "mecanum", "robot")
#: Phases reported through ``on_phase``, in order.
PHASES = ("fired", "in_flight", "settling", "classifying")
#: ``on_phase(phase)``: called with each of :data:`PHASES` once, in order.
PhaseCallback = typing.Callable[[str], None]
#: ``on_pose(t_s, position (x, y, z) m, orientation (x, y, z, w))``: the base pose at ``pose_rate_hz``.
PoseCallback = typing.Callable[[float, typing.Sequence[float], typing.Sequence[float]], None]
#: Smallest cosine between the push and the edge normal (``yaw_of_push`` angles up to about +-84 deg).
MIN_PUSH_TOWARDS_EDGE = 0.1


#: ``launch_twin.launcher.model`` values: how the cylinder drives the push plate (module docstring, "Launch").
LAUNCHER_MODELS = ("stroke", "push_through")
#: Pa per psi (the paper's regulator reads psi).
PA_PER_PSI = 6894.757


def _setting(default: typing.Any, description: str, value_range: typing.Optional[tuple] = None) -> typing.Any:
    """A settings field with the project's metadata (``description``, and ``range`` (low, high) when numeric)."""
    metadata = {"description": description, **({"range": value_range} if value_range is not None else {})}
    if isinstance(default, list):
        return dataclasses.field(default_factory=lambda: list(default), metadata=metadata)
    return dataclasses.field(default=default, metadata=metadata)


@dataclasses.dataclass
class LauncherSpec:
    """The launcher's run, ledge and cylinder (``launch_twin.launcher``); metres (module docstring, "Launch").

    Sources: ``run_length_m``, ``stroke_m``, the 25 mm bore and the regulator's 30 / 60 psi for 0.8 / 1.5 m/s are
    the paper's (section 2.2); ``ledge_rolling_friction`` and ``speed_bias_fraction`` are unknowns (0 = none), for
    calibration and the robust draws."""

    run_length_m: float = _setting(0.34, "travel of the robot's foremost point from its start to the edge, m "
                                         "(paper 2.2: the speed gate's run)", (0.05, 2.0))
    ledge_depth_m: float = _setting(0.0, "base plate and table behind the edge, m; 0 = derived from the robot",
                                    (0.0, 20.0))
    ledge_width_m: float = _setting(0.0, "base plate along the edge, m; 0 = derived from the robot", (0.0, 20.0))
    start_clearance_m: float = _setting(0.0005, "gap under the lowest wheel when placed on the plate, m",
                                        (0.0, 0.01))
    model: str = _setting("stroke", "how the cylinder drives the push plate: stroke (the paper's cylinder: pushes "
                                    "for stroke_m, then stops; the robot coasts to the edge) | push_through (the "
                                    "plate drives the robot at the launch speed until it goes over the edge)")
    stroke_m: float = _setting(0.15, "cylinder stroke: the plate's travel before it stops, m (paper 2.2: MAL 25 x "
                                     "150)", (0.01, 2.0))
    bore_m: float = _setting(0.0, "cylinder bore, m; 0 = derived: the paper's 25 mm on the built-in chassis, "
                                  "scaled with the square root of a heavier robot's mass", (0.0, 0.5))
    pressure_speeds_mps: typing.List[float] = _setting(
        [0.8, 1.5], "set launch speeds the regulator pressures below belong to, m/s (paper 2.2; as "
                    "config/rig.yaml valve.regulator)")
    pressures_psi: typing.List[float] = _setting(
        [30.0, 60.0], "regulator pressure per set speed above, psi (paper 2.2); between and beyond them the "
                      "pressure is interpolated linearly and held at the end values")
    ledge_rolling_friction: float = _setting(
        0.0, "UNKNOWN: the launcher base plate's own rolling friction, m (Bullet's rolling friction: a wheel "
             "coasting on it meets this x the wheel's friction more); slows the coast from the stroke's end to the "
             "edge", (0.0, 0.01))
    speed_bias_fraction: float = _setting(
        0.0, "UNKNOWN: systematic error of the lab's speed setting, fraction of the set speed (the gate accepts "
             "launches within speed_gate.tolerance_fraction of it)", (-0.15, 0.15))

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first unusable field (a ledge size or bore of 0 is derived from the
        robot)."""
        if not self.run_length_m > 0:
            raise ValueError(f"run_length_m must be > 0, got {self.run_length_m}")
        for name in ("ledge_depth_m", "ledge_width_m"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"{name} must be >= 0 (0 = derived from the robot), got {getattr(self, name)}")
        if self.ledge_depth_m and self.ledge_depth_m <= self.run_length_m:
            raise ValueError(f"ledge_depth_m {self.ledge_depth_m} must exceed run_length_m {self.run_length_m}")
        if not 0 <= self.start_clearance_m < 0.01:
            raise ValueError(f"start_clearance_m must be in [0, 0.01), got {self.start_clearance_m}")
        if self.model not in LAUNCHER_MODELS:
            raise ValueError(f"model must be one of {', '.join(LAUNCHER_MODELS)}, got {self.model!r}")
        if not 0 < self.stroke_m <= 2.0:
            raise ValueError(f"stroke_m must be in (0, 2], got {self.stroke_m}")
        if not 0 <= self.bore_m <= 0.5:
            raise ValueError(f"bore_m must be in [0, 0.5] (0 = derived from the robot), got {self.bore_m}")
        speeds, pressures = list(self.pressure_speeds_mps), list(self.pressures_psi)
        if not speeds or len(speeds) != len(pressures):
            raise ValueError(f"pressure_speeds_mps ({len(speeds)}) and pressures_psi ({len(pressures)}) must be "
                             "non-empty and the same length")
        if not all(0 < s < math.inf for s in speeds) or any(b <= a for a, b in zip(speeds, speeds[1:])):
            raise ValueError(f"pressure_speeds_mps must be positive and increasing, got {speeds}")
        if not all(0 < p < math.inf for p in pressures):
            raise ValueError(f"pressures_psi must be positive, got {pressures}")
        if not 0 <= self.ledge_rolling_friction <= 0.01:
            raise ValueError(f"ledge_rolling_friction must be in [0, 0.01], got {self.ledge_rolling_friction}")
        if not -0.15 <= self.speed_bias_fraction <= 0.15:
            raise ValueError(f"speed_bias_fraction must be in [-0.15, 0.15], got {self.speed_bias_fraction}")

    def pressure_psi(self, speed_mps: float) -> float:
        """The regulator pressure (psi) the lab sets for a set speed of ``speed_mps``: linear between the
        configured pairs, the end values beyond them."""
        return float(np.interp(speed_mps, self.pressure_speeds_mps, self.pressures_psi))


@dataclasses.dataclass
class PushPlateSpec:
    """The launcher's push plate (``launch_twin.plate``): a box on a velocity-controlled prismatic joint; metres.

    ``offset_m`` shifts the plate sideways (+ = left of the push direction) off the chassis's path and
    ``yaw_bias_deg`` turns its face (counterclockwise from above) away from square to the push: the rig's
    asymmetry, which calibration can fit. ``max_force_n`` is the most the cylinder pushes with (a 25 mm bore
    gives about 100 N at 30 psi and 200 N at 60 psi); the plate's speed ramps from rest to the launch speed in
    ``ramp_s`` (the chassis is pushed up to speed through the plate, so the plate's offset and turn act on it).
    """

    width_m: float = 0.0
    height_m: float = 0.0
    thickness_m: float = 0.01
    mass_kg: float = 0.3
    clearance_m: float = 0.0
    max_force_n: float = 0.0
    ramp_s: float = 0.012
    offset_m: float = 0.0
    yaw_bias_deg: float = 0.0

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first unusable field (``width_m``, ``height_m`` and ``clearance_m`` of 0
        are derived from the robot: :mod:`~rollability_ros.core.sim.launcher_geometry`)."""
        for name in ("thickness_m", "mass_kg", "ramp_s"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")
        for name in ("width_m", "height_m", "max_force_n"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"{name} must be >= 0 (0 = derived from the robot), got {getattr(self, name)}")
        if not 0 <= self.clearance_m < 0.1:
            raise ValueError(f"clearance_m must be in [0, 0.1), got {self.clearance_m}")
        if not abs(self.offset_m) < 0.5:
            raise ValueError(f"offset_m must be within +-0.5 m, got {self.offset_m}")
        if not abs(self.yaw_bias_deg) <= 20:
            raise ValueError(f"yaw_bias_deg must be within +-20 deg, got {self.yaw_bias_deg}")


@dataclasses.dataclass
class FoamSpec:
    """The memory-foam layer under the impact region (``launch_twin.foam``)."""

    thickness_m: float = 0.05
    length_m: float = 2.5
    width_m: float = 3.0
    contact_stiffness_npm: float = _setting(2.0e4, "UNKNOWN: Bullet contact stiffness per contact point, N/m "
                                                   "(guessed: ~4 cm under a 1.3 m drop)", (1.0e3, 1.0e6))
    contact_damping_nspm: float = _setting(150.0, "UNKNOWN: Bullet contact damping per contact point, N s/m "
                                                  "(guessed: memory foam barely rebounds)", (0.0, 2000.0))
    lateral_friction: float = _setting(1.0, "UNKNOWN: the foam's own friction coefficient; Bullet multiplies it with "
                                            "the robot's (sim.lateral_friction 0.35) (guessed)", (0.3, 3.0))
    rolling_friction: float = _setting(0.01, "UNKNOWN: the foam's own rolling friction, m: a wheel on the foam meets "
                                             "this x the wheel's friction more (guessed: a wheel sinks in)",
                                       (0.0, 0.05))
    restitution: float = _setting(0.1, "UNKNOWN: the foam's own restitution; times the robot's 0.3 per contact "
                                       "(guessed)", (0.0, 1.0))

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first unusable field."""
        for name in ("thickness_m", "length_m", "width_m", "contact_stiffness_npm"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")
        for name in ("contact_damping_nspm", "lateral_friction", "rolling_friction"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)}")
        if not 0 <= self.restitution <= 1:
            raise ValueError(f"restitution must be in [0, 1], got {self.restitution}")

    def contact(self, ground_contact: typing.Mapping[str, float]) -> typing.Dict[str, float]:
        """The foam's ``changeDynamics`` keywords: ``ground_contact``'s spinning friction, the foam's own rest."""
        return {**ground_contact, "lateralFriction": self.lateral_friction, "rollingFriction": self.rolling_friction,
                "restitution": self.restitution,
                "contactStiffness": self.contact_stiffness_npm, "contactDamping": self.contact_damping_nspm}


@dataclasses.dataclass
class LaunchTwinOptions:
    """The twin's own parameters (``config/launch_twin.yaml``, namespace ``launch_twin``)."""

    angle_convention: str = "yaw_of_push"
    wheel_model: str = "auto"
    speed_sigma_fraction: float = 0.03
    angle_sigma_deg: float = 1.0
    wheel_side_friction_factor: float = _setting(
        0.1, "UNKNOWN: Mecanum wheels' friction along the axle / across it (guessed: the rollers slide)", (0.0, 1.0))
    wheel_rolling_friction: float = _setting(
        0.0002, "UNKNOWN: Bullet rolling friction of a Mecanum wheel, m (force ~ this / wheel radius x load; "
                "guessed so the chassis covers the 0.34 m run)", (0.0, 0.01))
    wheel_drag_torque_nm: float = _setting(
        0.0005, "UNKNOWN: back-drive drag of each unpowered wheel motor, N m (guessed)", (0.0, 0.05))
    wheel_friction_left_factor: float = 1.0
    wheel_friction_right_factor: float = 1.0
    max_attempts: int = 3
    pose_rate_hz: float = 30.0
    launcher: LauncherSpec = dataclasses.field(default_factory=LauncherSpec)
    plate: PushPlateSpec = dataclasses.field(default_factory=PushPlateSpec)
    foam: FoamSpec = dataclasses.field(default_factory=FoamSpec)
    designs: DesignSources = dataclasses.field(default_factory=DesignSources)

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first unusable field."""
        if self.angle_convention not in ANGLE_CONVENTIONS:
            raise ValueError(f"angle_convention must be one of {', '.join(ANGLE_CONVENTIONS)}, "
                             f"got {self.angle_convention!r}")
        if self.wheel_model not in WHEEL_MODELS:
            raise ValueError(f"wheel_model must be one of {', '.join(WHEEL_MODELS)}, got {self.wheel_model!r}")
        if not 0 <= self.speed_sigma_fraction <= 0.5:
            raise ValueError(f"speed_sigma_fraction must be in [0, 0.5], got {self.speed_sigma_fraction}")
        if not 0 <= self.angle_sigma_deg <= 30:
            raise ValueError(f"angle_sigma_deg must be in [0, 30], got {self.angle_sigma_deg}")
        if not 0 <= self.wheel_side_friction_factor <= 1:
            raise ValueError(f"wheel_side_friction_factor must be in [0, 1], got {self.wheel_side_friction_factor}")
        if self.wheel_rolling_friction < 0 or self.wheel_drag_torque_nm < 0:
            raise ValueError("wheel_rolling_friction and wheel_drag_torque_nm must be >= 0")
        for name in ("wheel_friction_left_factor", "wheel_friction_right_factor"):
            if not 0 < getattr(self, name) <= 5:
                raise ValueError(f"{name} must be in (0, 5], got {getattr(self, name)}")
        if not 1 <= self.max_attempts <= 20:
            raise ValueError(f"max_attempts must be in [1, 20], got {self.max_attempts}")
        if not self.pose_rate_hz > 0:
            raise ValueError(f"pose_rate_hz must be > 0, got {self.pose_rate_hz}")
        # one seam per swap: the settings of the launcher model not chosen cannot be honoured, so they are refused
        if self.launcher.model == "stroke" and self.plate.max_force_n:
            raise ValueError(f"plate.max_force_n ({self.plate.max_force_n} N) drives the push_through plate only; "
                             "the stroke cylinder pushes with launcher.pressures_psi x its bore: set it to 0 or "
                             "launcher.model to push_through")
        if self.launcher.model == "push_through" and self.launcher.bore_m:
            raise ValueError(f"launcher.bore_m ({self.launcher.bore_m} m) sizes the stroke cylinder only; the "
                             "push_through plate pushes with plate.max_force_n: set it to 0 or launcher.model to "
                             "stroke")


@dataclasses.dataclass
class LaunchTwinSettings(RobotChoice):
    """Everything a simulated launch needs (picklable); every field can be replaced per call (calibration).

    The robot launched is the built-in chassis (``robot``) unless ``urdf_robot`` names a mount link, chosen as
    for the trials (:class:`~rollability_ros.core.robots.urdf_robot.RobotChoice`: ``robot_model()``,
    ``profile_body(mesh)``).
    """

    physics: PhysicsParams = dataclasses.field(default_factory=PhysicsParams)
    robot: ChassisSpec = dataclasses.field(default_factory=ChassisSpec)
    trial: TrialSettings = dataclasses.field(default_factory=TrialSettings)
    twin: LaunchTwinOptions = dataclasses.field(default_factory=LaunchTwinOptions)
    urdf_robot: UrdfRobotSpec = dataclasses.field(default_factory=UrdfRobotSpec)


#: settings field -> config namespace
_SECTIONS = {"physics": "sim", "robot": "robot", "trial": "trial", "twin": "launch_twin", "urdf_robot": "urdf_robot"}


#: The namespace of the twin's own parameters (``config/launch_twin.yaml``), and every namespace the twin reads.
TWIN_NAMESPACE = _SECTIONS["twin"]
TWIN_SECTIONS = frozenset(_SECTIONS.values())


def twin_files(paths: typing.Sequence[str], namespaces: typing.Iterable[str] = (TWIN_NAMESPACE,)) -> typing.List[str]:
    """The parameter files among ``paths`` that set parameters in ``namespaces`` (default: the twin's own), as
    absolute paths: those a command appends to its twin's file list (``objective.twin_config``,
    ``rig.twin_config``) so that the twin reads them."""
    prefixes = tuple(namespace + "." for namespace in namespaces)
    return [os.path.abspath(resolve_config_path(path)) for path in paths
            if any(name.startswith(prefixes) for name in load_parameters([path]))]


def launch_twin_settings_from_parameters(flat: typing.Mapping[str, typing.Any],
                                         overrides: typing.Optional[typing.Mapping[str, typing.Any]] = None
                                         ) -> LaunchTwinSettings:
    """Build :class:`LaunchTwinSettings` from flat ``{dotted name: value}`` parameters (e.g. a node's).

    ``overrides`` maps dotted *settings* names (``"twin.foam.contact_stiffness_npm"``, ``"physics.restitution"``,
    ``"robot.body_mass_kg"``) to values; they are checked like file values (:class:`ConfigError` if unknown or bad).
    """
    nested: typing.Dict[str, typing.Any] = {name: section(flat, prefix) for name, prefix in _SECTIONS.items()}
    for dotted, value in (overrides or {}).items():
        *parents, leaf = dotted.split(".")
        node = nested
        for part in parents:
            node = node.setdefault(part, {})
            if not isinstance(node, dict):
                raise ConfigError(f"override {dotted}: {part} is not a group of settings")
        node[leaf] = value
    return from_mapping(LaunchTwinSettings, nested, "launch twin settings")


def load_launch_twin_settings(config_paths: typing.Sequence[str] = ("sim", "robot", "launch_twin"),
                              node_name: str = "/**",
                              overrides: typing.Optional[typing.Mapping[str, typing.Any]] = None
                              ) -> LaunchTwinSettings:
    """Read :class:`LaunchTwinSettings` from ROS 2 parameter files (names of shipped files or paths).

    Namespaces: ``sim`` and ``trial`` (sim.yaml), ``robot`` (robot.yaml), ``launch_twin`` (launch_twin.yaml),
    ``urdf_robot`` (a URDF robot's config such as husky.yaml: that robot is launched instead of the chassis).
    Missing keys keep their defaults; see :func:`launch_twin_settings_from_parameters` for ``overrides``.
    """
    return launch_twin_settings_from_parameters(load_parameters(list(config_paths), node_name), overrides)


@dataclasses.dataclass(frozen=True)
class LaunchResult:
    """One simulated launch. Times are simulated seconds from the push; positions metres, world frame.

    ``final_orientation`` is the chassis base (x, y, z, w) at the end; ``launch_speed_mps`` and
    ``launch_angle_deg`` the drawn actual values; ``travel_time_s``, ``measured_speed_mps``, ``flight_time_s``
    and ``landing_position_m`` are as in the module docstring, NaN when the event did not happen;
    ``landing_position_m`` is the base origin at the first foam contact; ``peak_deceleration_mps2`` the largest change of the base's velocity over one step
    from the step of that contact on, divided by the step (m/s^2): the impact an accelerometer on the chassis
    would see. ``edge_speed_mps`` is the base's speed along the push when its foremost point crosses the edge
    (NaN if it never does). ``invalid_reason`` is "" for a valid launch, else why it is no launch (it did not
    leave the ledge, it landed outside the foam); ``attempts`` counts the launches :func:`simulate_valid_launch`
    made to get this one, and ``seed`` is the seed this launch was simulated with (the kept retry's
    :func:`attempt_seed`): :func:`simulate_launch` with it repeats this launch exactly. ``decided``: ended by the
    early decision (``trial.early_decision``, :func:`step_launch`): ``upright`` is the decided outcome, ``settled``
    true, ``tilt_deg`` and ``final_orientation`` those at the decision.

    ``upright`` is the rig's verdict (:func:`rig_verdict`, module docstring "Outcome"): at rest on its wheels,
    wherever. Beside it, as data that never decides it: ``rest_surface`` where it came to rest ("pad": the base
    origin over the foam pad's extent, "floor": beyond it, "ledge": it never went over), ``rest_position_m`` the
    base origin at the end (x, y, z), ``rest_distance_m`` its horizontal distance from where it crossed the edge
    line, ``time_to_rest_s`` from the first landing until the rest rule held (NaN when it hit the time cap, never
    landed, or the early decision ended it: a decided launch's ``rest_*`` are where it was at the decision, clear of
    the pad's edges by the decision's rule), and ``plate_speed_mps`` the speed the cylinder drove the plate at
    (the stroke model's solved speed for this launch's set speed, :func:`launch_drive`).
    """

    upright: bool
    final_orientation: tuple
    travel_time_s: float
    measured_speed_mps: float
    launch_speed_mps: float
    settled: bool
    sim_time_s: float
    steps: int
    tilt_deg: float
    launch_angle_deg: float = 0.0
    flight_time_s: float = NOT_MEASURED
    landing_position_m: tuple = (NOT_MEASURED,) * 3
    peak_deceleration_mps2: float = 0.0
    edge_speed_mps: float = NOT_MEASURED
    invalid_reason: str = ""
    attempts: int = 1
    seed: int = NO_SEED
    decided: bool = False
    rest_surface: str = ""
    rest_position_m: tuple = (NOT_MEASURED,) * 3
    rest_distance_m: float = NOT_MEASURED
    time_to_rest_s: float = NOT_MEASURED
    plate_speed_mps: float = NOT_MEASURED

    @property
    def valid(self) -> bool:
        """True when the launch happened as the rig launches: the chassis left the ledge and landed on the foam."""
        return not self.invalid_reason

    @property
    def final_orientation_xyzw(self) -> tuple:
        """``final_orientation``, under the name :func:`rollability_ros.core.rig.rig_session.simulated_outcome` reads."""
        return self.final_orientation


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
        "cylinder_bore_m": launcher.bore_m})
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


@dataclasses.dataclass(frozen=True)
class LaunchDrive:
    """How the cylinder drives the push plate in launches of one set speed (module docstring, "Launch"): the
    plate's speed is ``speed_ratio`` x the launch's drawn gate speed, reached with at most ``force_n`` (from rest,
    within ``ramp_s``), and held until the plate has travelled ``stroke_m`` (inf: until the robot goes over the
    edge, ``push_through``) or the robot goes over the edge."""

    model: str
    speed_ratio: float
    force_n: float
    stroke_m: float
    ramp_s: float

    def plate_speed_mps(self, gate_speed_mps: float) -> float:
        """The plate's speed (m/s) for a launch whose drawn gate speed is ``gate_speed_mps``."""
        return self.speed_ratio * gate_speed_mps

    def plate_spec(self, spec: PushPlateSpec) -> PushPlateSpec:
        """``spec`` with this drive's force and ramp (what the twins' plates read)."""
        return dataclasses.replace(spec, max_force_n=self.force_n, ramp_s=self.ramp_s)


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
    within :data:`SOLVE_TOLERANCE`. ``ValueError`` naming the settings when no plate speed up to
    :data:`SOLVE_MAX_RATIO` x the set speed gets there (a cylinder too weak for the robot)."""
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
            raise ValueError(
                f"the stroke launcher cannot launch this robot at {set_speed_mps} m/s: the gate reads "
                f"{set_speed_mps + low_miss:.3f} m/s with the plate at {low * set_speed_mps:.2f} m/s and {force_n:.0f} N "
                f"(launch_twin.launcher.pressures_psi {launcher.pressure_psi(set_speed_mps):.0f} psi x bore "
                f"{launcher.bore_m * 1000:.1f} mm) over the stroke_m {launcher.stroke_m} m; raise the pressure or "
                "the bore, or lower the rolling resistance")
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


def profile_body(configuration: str, settings: LaunchTwinSettings) -> typing.Optional[ProfileBody]:
    """The :class:`ProfileBody` mounted for ``configuration`` (None = baseline); see :mod:`designs`."""
    mesh = profile_mesh_for(configuration, settings.twin.designs)
    return None if mesh is None else settings.profile_body(mesh)


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


def _static_box(pybullet, client, half_extents, centre, contact):
    shape = pybullet.createCollisionShape(pybullet.GEOM_BOX, halfExtents=list(half_extents), physicsClientId=client)
    body = pybullet.createMultiBody(baseMass=0.0, baseCollisionShapeIndex=shape, basePosition=list(centre),
                                    physicsClientId=client)
    set_contact(client, body, contact)
    return body


def build_launch_world(client: int, settings: LaunchTwinSettings, height_m: float) -> typing.Tuple[int, int, int]:
    """Empty ``client``'s world and build floor, foam and ledge (module docstring); return
    ``(foam_id, ledge_id, floor_id)``."""
    pybullet = require("pybullet", feature="the launch twin")
    physics, foam, launcher = settings.physics, settings.twin.foam, settings.twin.launcher
    floor_id = reset_world(client, physics)
    foam_id = _static_box(pybullet, client, (foam.length_m / 2, foam.width_m / 2, foam.thickness_m / 2),
                          (foam.length_m / 2, 0.0, foam.thickness_m / 2), foam.contact(physics.ground_contact()))
    top = foam.thickness_m + height_m
    ledge_id = _static_box(pybullet, client, (launcher.ledge_depth_m / 2, launcher.ledge_width_m / 2, top / 2),
                           (-launcher.ledge_depth_m / 2, 0.0, top / 2), ledge_contact(settings))
    return foam_id, ledge_id, floor_id


def ledge_contact(settings: LaunchTwinSettings) -> typing.Dict[str, float]:
    """The launcher base plate's ``changeDynamics`` keywords: the ground contact of ``config/sim.yaml`` with
    ``launcher.ledge_rolling_friction`` added to its own rolling friction (the coast's unknown resistance)."""
    contact = dict(settings.physics.ground_contact())
    contact["rollingFriction"] = contact.get("rollingFriction", 0.0) + settings.twin.launcher.ledge_rolling_friction
    return contact


def wheel_side_m(pybullet: types.ModuleType, client: int, robot: SpawnedRobot, link: int) -> float:
    """Where wheel ``link`` sits across the robot: its y in the base frame (m; + = left)."""
    base_position, base_orientation = pybullet.getBasePositionAndOrientation(robot.body_id, physicsClientId=client)
    link_position = pybullet.getLinkState(robot.body_id, link, physicsClientId=client)[4]
    inverse_position, inverse_orientation = pybullet.invertTransform(base_position, base_orientation)
    return pybullet.multiplyTransforms(inverse_position, inverse_orientation, link_position, (0, 0, 0, 1))[0][1]


def mecanum_wheels(settings: LaunchTwinSettings) -> bool:
    """True when the twin gives the wheels its Mecanum contact and drag (``wheel_model`` mecanum, or auto on the
    built-in chassis); False when the robot keeps its own (robot, or auto on a URDF robot), as in the trials."""
    wheel_model = settings.twin.wheel_model
    return wheel_model == "mecanum" or (wheel_model == "auto" and not settings.urdf_robot.selected)


def _set_wheels(pybullet, client, robot, options, lateral_friction, mecanum):
    """Give the wheel links the left / right friction factors (of the robot's ``lateral_friction``) and, with
    ``mecanum``, the twin's Mecanum side friction, rolling friction and motor drag; without it the wheels keep the
    robot's own rolling friction and joint drag (the trials')."""
    for link in robot.wheel_links:
        left = wheel_side_m(pybullet, client, robot, link) >= 0.0
        side_factor = options.wheel_friction_left_factor if left else options.wheel_friction_right_factor
        pybullet.changeDynamics(robot.body_id, link, lateralFriction=lateral_friction * side_factor,
                                physicsClientId=client)
        if mecanum:
            axis = pybullet.getJointInfo(robot.body_id, link, physicsClientId=client)[13]
            factors = [1.0 - (1.0 - options.wheel_side_friction_factor) * abs(a) for a in axis]  # a link unit axis
            pybullet.changeDynamics(robot.body_id, link, anisotropicFriction=factors,
                                    rollingFriction=options.wheel_rolling_friction, physicsClientId=client)
    if not mecanum:
        return
    pybullet.setJointMotorControlArray(robot.body_id, list(robot.wheel_links), pybullet.VELOCITY_CONTROL,
                                       targetVelocities=[0.0] * len(robot.wheel_links),
                                       forces=[options.wheel_drag_torque_nm] * len(robot.wheel_links),
                                       physicsClientId=client)


def apply_wheel_model(pybullet: types.ModuleType, client: int, robot: SpawnedRobot,
                      settings: LaunchTwinSettings) -> None:
    """The twin's wheel contact and drag (module docstring, "Wheels") on ``robot``'s wheel links: every PyBullet
    model of the twin's rig (the launch, the characterisation roll-out) uses this one."""
    _set_wheels(pybullet, client, robot, settings.twin, settings.physics.lateral_friction, mecanum_wheels(settings))


class PhaseReporter:
    """Reports each of :data:`PHASES` once and in order, filling in any skipped before the one reached."""

    def __init__(self, on_phase: typing.Optional[PhaseCallback]) -> None:
        self._on_phase = on_phase
        self._next = 0

    def reach(self, phase: str) -> None:
        """Report ``phase`` (one of :data:`PHASES`), after any not yet reported before it; nothing if already."""
        target = PHASES.index(phase)
        while self._next <= target:
            if self._on_phase is not None:
                self._on_phase(PHASES[self._next])
            self._next += 1


def _bounds_m(pybullet, client, robot):
    """The world bounding box of ``robot`` (a SpawnedRobot) from :func:`_corners_m`: ``(low (3,), high (3,))`` (m)."""
    corners = _corners_m(pybullet, client, robot)
    return corners.min(axis=0), corners.max(axis=0)


def _place_on_plate(pybullet, client, robot, orientation, clearance_m, xy_m, plate_z):
    """:func:`place_on_ground` on the launcher's top, then lowered so the lowest of :func:`_corners_m` (not of
    Bullet's looser box of a profile mesh) is ``clearance_m`` above it."""
    place_on_ground(client, robot.body_id, orientation, clearance_m, xy_m, plate_z)
    position = list(pybullet.getBasePositionAndOrientation(robot.body_id, physicsClientId=client)[0])
    position[2] += plate_z + clearance_m - float(_bounds_m(pybullet, client, robot)[0][2])
    pybullet.resetBasePositionAndOrientation(robot.body_id, position, orientation, physicsClientId=client)


def place_on_launcher(pybullet: types.ModuleType, client: int, robot: SpawnedRobot, orientation: typing.Sequence[float],
                      push: npt.ArrayLike, settings: LaunchTwinSettings, height_m: float) -> float:
    """Put the chassis at rest on the plate so that its foremost point reaches the edge after ``run_length_m``
    along ``push`` (unit (3,)); the base origin's path passes through the edge's midpoint. Return the foremost
    point's offset ahead of the base origin along x (m).

    Raises ``ValueError`` when the robot placed there is not wholly over the ledge (``ledge_depth_m`` behind the
    edge, ``ledge_width_m`` along it): a robot too large for the configured launcher.
    """
    launcher = settings.twin.launcher
    plate_z = settings.twin.foam.thickness_m + height_m
    _place_on_plate(pybullet, client, robot, orientation, launcher.start_clearance_m, (0.0, 0.0), plate_z)
    base_x = pybullet.getBasePositionAndOrientation(robot.body_id, physicsClientId=client)[0][0]
    lead_m = float(_bounds_m(pybullet, client, robot)[1][0]) - base_x
    _place_on_plate(pybullet, client, robot, orientation, launcher.start_clearance_m,
                    launcher_start_xy(lead_m, push, launcher), plate_z)
    low, high = _bounds_m(pybullet, client, robot)
    check_fits_launcher(low, high, launcher)
    return lead_m


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
    """Where the push plate starts (every twin's rule, module docstring "Launch"): its base ``centre_m`` (3,),
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


class LaunchPlate(typing.Protocol):
    """What :func:`step_launch` drives of a twin's push plate (:class:`PushPlate`, the MuJoCo twin's plate)."""

    driving: bool

    def drive(self, speed_mps: float, time_s: float) -> None:
        """Drive along the push at ``time_s`` (s) after the fire, ramping to ``speed_mps`` (m/s) over ``ramp_s``."""

    def reached_edge(self) -> bool:
        """True once the plate's face has reached the edge line x = 0."""

    def travel_m(self) -> float:
        """How far the plate has moved along the push from its start (m)."""

    def stop(self) -> None:
        """Brake the plate to rest."""


class PushPlate:
    """The push plate on its prismatic joint: placed behind the chassis, driven at the launch speed along the push
    until the chassis goes over the edge (or the plate reaches it), then braked (module docstring, "Launch")."""

    def __init__(self, pybullet: types.ModuleType, client: int, robot: SpawnedRobot, push: npt.ArrayLike,
                 spec: PushPlateSpec, plate_z: float, ignore_bodies: typing.Iterable[int]) -> None:
        self._pybullet, self._client, self.spec = pybullet, client, spec
        self.push = np.asarray(push, dtype=np.float64)
        corners = _corners_m(pybullet, client, robot)
        base = np.asarray(pybullet.getBasePositionAndOrientation(robot.body_id, physicsClientId=client)[0])
        placement = plate_placement(float((corners @ self.push).min()), base, self.push, spec, plate_z)
        shape = pybullet.createCollisionShape(
            pybullet.GEOM_BOX, halfExtents=[spec.thickness_m / 2, spec.width_m / 2, spec.height_m / 2],
            collisionFrameOrientation=pybullet.getQuaternionFromEuler([0.0, 0.0, placement.bias_rad]),
            physicsClientId=client)
        self.body_id = pybullet.createMultiBody(
            baseMass=0.0, basePosition=list(placement.centre_m),
            baseOrientation=pybullet.getQuaternionFromEuler([0, 0, placement.yaw_rad]),
            linkMasses=[spec.mass_kg], linkCollisionShapeIndices=[shape], linkVisualShapeIndices=[-1],
            linkPositions=[[0, 0, 0]], linkOrientations=[[0, 0, 0, 1]], linkInertialFramePositions=[[0, 0, 0]],
            linkInertialFrameOrientations=[[0, 0, 0, 1]], linkParentIndices=[0],
            linkJointTypes=[pybullet.JOINT_PRISMATIC], linkJointAxis=[[1, 0, 0]], physicsClientId=client)
        pybullet.changeDynamics(self.body_id, 0, lateralFriction=0.3, linearDamping=0.0, physicsClientId=client)
        for other in ignore_bodies:
            pybullet.setCollisionFilterPair(self.body_id, other, 0, -1, 0, physicsClientId=client)
        self.face_x_m = placement.face_x_m
        # bounding boxes of turned links overstate the rear: close the rest of the gap to 1 mm along the push
        gaps = [point[8] for point in pybullet.getClosestPoints(self.body_id, robot.body_id, 1.0, linkIndexA=0,
                                                                  physicsClientId=client)]
        self.start_m = max(0.0, min(gaps) - 0.001) if gaps else 0.0
        pybullet.resetJointState(self.body_id, 0, self.start_m, 0.0, physicsClientId=client)
        self.driving = False
        self._at_speed = False

    def drive(self, speed_mps: float, time_s: float) -> None:
        """Drive the plate along the push at ``time_s`` after the fire: its speed ramps from rest to ``speed_mps``
        over ``ramp_s``, then holds, with at most ``max_force_n``."""
        if self._at_speed:
            return
        target_mps = speed_mps * min(1.0, time_s / self.spec.ramp_s)
        self._pybullet.setJointMotorControl2(self.body_id, 0, self._pybullet.VELOCITY_CONTROL,
                                             targetVelocity=target_mps, force=self.spec.max_force_n,
                                             physicsClientId=self._client)
        self._at_speed = time_s >= self.spec.ramp_s
        self.driving = True

    def reached_edge(self) -> bool:
        """True once the plate's face has reached the edge line x = 0."""
        travel_m = self._pybullet.getJointState(self.body_id, 0, physicsClientId=self._client)[0]
        return bool(self.face_x_m + travel_m * self.push[0] >= 0.0)

    def travel_m(self) -> float:
        """How far the plate has moved along the push from its start (m)."""
        return float(self._pybullet.getJointState(self.body_id, 0, physicsClientId=self._client)[0]) - self.start_m

    def stop(self) -> None:
        """Brake the plate to rest (the cylinder at the end of its push)."""
        self._pybullet.setJointMotorControl2(self.body_id, 0, self._pybullet.VELOCITY_CONTROL, targetVelocity=0.0,
                                             force=self.spec.max_force_n * 10, physicsClientId=self._client)
        self.driving = False


def _corners_m(pybullet, client, robot):
    """Points bounding ``robot`` (a SpawnedRobot) in the world: the corners of each link's world bounding box, and
    the profile's hull vertices placed exactly (Bullet's box of a mesh link on rotated inertial axes is up to
    twice the mesh's size); (n, 3) array (m)."""
    body_id = robot.body_id
    corners = []
    for link in range(-1, pybullet.getNumJoints(body_id, physicsClientId=client)):
        if link == robot.profile_link and robot.profile_points_m is not None:
            position, orientation = pybullet.getLinkState(body_id, link, physicsClientId=client)[4:6]
            rotation = np.asarray(pybullet.getMatrixFromQuaternion(orientation)).reshape(3, 3)
            corners.extend((np.asarray(robot.profile_points_m) @ rotation.T + position).tolist())
            continue
        low, high = pybullet.getAABB(body_id, link, physicsClientId=client)
        corners.extend([(x, y, z) for x in (low[0], high[0]) for y in (low[1], high[1]) for z in (low[2], high[2])])
    return np.asarray(corners, dtype=np.float64)


def attempt_seed(seed: int, attempt: int) -> int:
    """The seed of retry ``attempt`` (0 = the launch's own ``seed``) of :func:`simulate_valid_launch`."""
    if attempt == 0:
        return int(seed)
    state = np.random.SeedSequence(int(seed), spawn_key=(0x1A7, int(attempt))).generate_state(1, dtype=np.uint32)
    return int(state[0]) & 0x7FFFFFFF


def simulate_valid_launch(condition: LaunchCondition, settings: LaunchTwinSettings, seed: int,
                          on_phase: typing.Optional[PhaseCallback] = None,
                          on_pose: typing.Optional[PoseCallback] = None, profile: typing.Optional[ProfileBody] = None,
                          use_profile: bool = False) -> LaunchResult:
    """:func:`simulate_launch`, repeated with :func:`attempt_seed` seeds while the launch is invalid, at most
    ``launch_twin.max_attempts`` times in all; returns the first valid launch or the last invalid one, with
    ``attempts`` set. The callbacks follow the first attempt only (a retry starts again from the push)."""
    for attempt in range(settings.twin.max_attempts):
        first = attempt == 0
        result = simulate_launch(condition, settings, attempt_seed(seed, attempt), on_phase if first else None,
                                 on_pose if first else None, profile=profile, use_profile=use_profile)
        if result.valid:
            break
    return dataclasses.replace(result, attempts=attempt + 1)


def simulate_launch(condition: LaunchCondition, settings: LaunchTwinSettings, seed: int,
                    on_phase: typing.Optional[PhaseCallback] = None, on_pose: typing.Optional[PoseCallback] = None,
                    profile: typing.Optional[ProfileBody] = None, use_profile: bool = False) -> LaunchResult:
    """Launch ``condition``'s configuration off the simulated ledge and classify it (module docstring).

    Parameters
    ----------
    condition : rollability_ros.core.records.LaunchCondition
        Configuration id, ledge height above the foam (m), nominal launch speed (m/s), angle (deg).
    settings : LaunchTwinSettings
    seed : int
        >= 0; draws the speed and angle scatter. Same seed, condition and settings -> identical result.
    on_phase : callable(str), optional
        Called with each of :data:`PHASES` once, in order.
    on_pose : callable(t_s, position_xyz, orientation_xyzw), optional
        The chassis base pose at ``pose_rate_hz`` of simulated time (t = 0 first), metres and (x, y, z, w).
    profile : ProfileBody or None, optional
        With ``use_profile``, the profile to mount instead of the configuration's (None = bare chassis): a
        candidate of an optimization (:mod:`rollability_ros.core.sim.objectives`).

    Returns
    -------
    LaunchResult
        Raises ``ValueError`` for a bad condition, seed or configuration id, or a robot that does not fit on the
        launcher (:func:`place_on_launcher`).
    """
    check_engine("launch", settings.physics.engine)
    condition.validate()
    settings = sized_for_robot(settings)[0]
    if not use_profile:
        profile = profile_body(condition.configuration, settings)
    return LAUNCH_ENGINES.get(settings.physics.engine).simulate(condition, settings, seed, profile, on_phase, on_pose,
                                                                drive=launch_drive(settings, condition.speed_mps))


class BulletLaunch(LaunchEngine):
    """``sim.engine: pybullet``: each launch in a fresh PyBullet world (:func:`simulate_launch`)."""

    @classmethod
    def simulate(cls, condition: LaunchCondition, settings: LaunchTwinSettings, seed: int,
                 profile: typing.Optional[ProfileBody], on_phase: typing.Optional[PhaseCallback] = None,
                 on_pose: typing.Optional[PoseCallback] = None, *,
                 drive: "typing.Optional[LaunchDrive]" = None,
                 until_edge: bool = False) -> LaunchResult:
        """One launch of the sized twin ``settings`` carrying ``profile`` with the cylinder's ``drive`` (see
        :func:`simulate_launch`; None: :func:`launch_drive` of the condition's speed); ``until_edge``: stop once the
        foremost point crosses the edge (the speed solve)."""
        options = settings.twin
        drive = drive or launch_drive(settings, condition.speed_mps)
        pybullet = require("pybullet", feature="the launch twin")
        speed_mps, angle_deg, push = launch_plan(condition, seed, options)
        angle = math.radians(angle_deg)
        model = settings.robot_model()
        client = connect()
        try:
            foam_id, ledge_id, floor_id = build_launch_world(client, settings, condition.height_m)
            orientation = pybullet.getQuaternionFromEuler([0.0, 0.0, angle])
            robot = model.spawn(client, profile, (0.0, 0.0, 5.0), orientation,
                                time_step_s=settings.physics.time_step_s)
            set_contact(client, robot.body_id, settings.physics.body_contact())
            apply_wheel_model(pybullet, client, robot, settings)
            lead_m = place_on_launcher(pybullet, client, robot, orientation, push, settings, condition.height_m)
            plate = PushPlate(pybullet, client, robot, push, drive.plate_spec(options.plate),
                              options.foam.thickness_m + condition.height_m, (floor_id, foam_id, ledge_id))
            world = _BulletLaunchWorld(pybullet, client, robot, foam_id, floor_id, settings, profile)
            tracker = LaunchTracker(world, lead_m, PhaseReporter(on_phase), push)
            steps, settled, decision = step_launch(world, plate, tracker, settings, on_pose,
                                                   drive.plate_speed_mps(speed_mps), drive.stroke_m, until_edge)
            tilt = model.tilt_deg(client, robot)
            if decision is None:
                upright = rig_verdict(tilt, wheels_down(pybullet, client, robot, model, (foam_id, floor_id, ledge_id)),
                                      model)
            else:
                upright = decision
            position, orientation = pybullet.getBasePositionAndOrientation(robot.body_id, physicsClientId=client)
        finally:
            disconnect(client)
        return launch_result(tracker, settings, (steps, settled, decision), (upright, tilt, orientation),
                             (speed_mps, angle_deg), seed, position, drive.plate_speed_mps(speed_mps))


def wheels_down(pybullet: types.ModuleType, client: int, robot: SpawnedRobot, model: RobotModel,
                surfaces: typing.Iterable[int]) -> int:
    """How many of ``robot``'s wheel links are within the model's ``contact_tolerance_m`` of any of the bodies
    ``surfaces`` (the twin's pad, floor and ledge): the wheels it stands on, wherever (:func:`rig_verdict`)."""
    surfaces = tuple(surfaces)
    return sum(any(pybullet.getClosestPoints(robot.body_id, surface, model.contact_tolerance_m, linkIndexA=link,
                                             physicsClientId=client) for surface in surfaces)
               for link in robot.wheel_links)


def launch_result(tracker: "LaunchTracker", settings: LaunchTwinSettings,
                  run: typing.Tuple[int, bool, typing.Optional[bool]],
                  classified: typing.Tuple[bool, float, typing.Sequence[float]], drawn: typing.Tuple[float, float],
                  seed: int, rest_position_m: typing.Sequence[float] = (NOT_MEASURED,) * 3,
                  plate_speed_mps: float = NOT_MEASURED) -> LaunchResult:
    """The :class:`LaunchResult` of a launch (every twin's): ``run`` = ``(steps, settled, decision)`` of
    :func:`step_launch`, ``classified`` = ``(upright, tilt_deg, final orientation (x, y, z, w))``, ``drawn`` =
    ``(launch speed m/s, angle deg)`` of :func:`launch_plan`, ``rest_position_m`` the base origin at the end (m),
    ``plate_speed_mps`` the cylinder's speed in this launch."""
    steps, settled, decision = run
    upright, tilt, orientation = classified
    speed_mps, angle_deg = drawn
    options = settings.twin
    travel_s = tracker.front.time_s
    sim_time_s = steps * settings.physics.time_step_s
    rest = tuple(float(v) for v in rest_position_m)
    foam = options.foam
    if not tracker.went_over:
        surface = "ledge"
    else:
        surface = "pad" if 0.0 <= rest[0] <= foam.length_m and abs(rest[1]) <= foam.width_m / 2 else "floor"
    rested = settled and decision is None and not math.isnan(tracker.landed_s)
    return LaunchResult(upright=bool(upright), final_orientation=tuple(float(v) for v in orientation),
                        travel_time_s=travel_s, measured_speed_mps=options.launcher.run_length_m / travel_s,
                        launch_speed_mps=speed_mps, settled=bool(settled),
                        sim_time_s=sim_time_s, steps=steps, tilt_deg=float(tilt),
                        launch_angle_deg=angle_deg, flight_time_s=tracker.landed_s - tracker.base.time_s,
                        landing_position_m=tracker.landing_m,
                        peak_deceleration_mps2=tracker.peak_deceleration_mps2, edge_speed_mps=tracker.edge_speed_mps,
                        invalid_reason=invalid_reason(tracker.went_over, tracker, options.foam), seed=int(seed),
                        decided=decision is not None, rest_surface=surface, rest_position_m=rest,
                        rest_distance_m=math.hypot(rest[0] - tracker.edge_xy_m[0], rest[1] - tracker.edge_xy_m[1]),
                        time_to_rest_s=sim_time_s - tracker.landed_s if rested else NOT_MEASURED,
                        plate_speed_mps=float(plate_speed_mps))


def rig_verdict(tilt_deg: float, wheels_down: int, robot_model: "RobotModel") -> bool:
    """The rig's outcome rule (module docstring, "Outcome"), every twin's verdict: at rest with the body's up axis
    within ``upright_tilt_deg`` of world up (``config/robot.yaml``; the rig's IMU classifier uses the same 30 deg,
    ``config/rig.yaml`` ``imu_outcome.tilt_threshold_deg``) and on its wheels: at least ``min_wheels_in_contact``
    wheels (``wheels_down``) within ``contact_tolerance_m`` of whatever surface it rests on (pad, floor or ledge)."""
    return tilt_deg <= robot_model.upright_tilt_deg and wheels_down >= robot_model.min_wheels_in_contact


def launch_plan(condition: LaunchCondition, seed: int,
                options: LaunchTwinOptions) -> typing.Tuple[float, float, np.ndarray]:
    """The drawn ``(launch speed m/s, angle deg, push direction (3,))`` of a launch of ``condition`` with ``seed``
    (module docstring, "Angle" and "Launch"); ``ValueError`` for an angle that pushes along or away from the edge."""
    speed_mps, angle_deg = launch_draws(seed, condition.speed_mps, condition.angle_deg, options)
    push_yaw = math.radians(angle_deg) if options.angle_convention == "yaw_of_push" else 0.0
    push = np.array([math.cos(push_yaw), math.sin(push_yaw), 0.0])
    if push[0] < MIN_PUSH_TOWARDS_EDGE:
        raise ValueError(f"angle {angle_deg:.1f} deg pushes along or away from the edge under {options.angle_convention}"
                         f" (|angle| must stay below {math.degrees(math.acos(MIN_PUSH_TOWARDS_EDGE)):.0f} deg)")
    return speed_mps, angle_deg, push


def invalid_reason(went_over: bool, tracker: "LaunchTracker", foam: FoamSpec) -> str:
    """Why a launch is no launch ("" when it is one): see :attr:`LaunchResult.invalid_reason`."""
    if not went_over:
        return "did not leave the ledge"
    if tracker.floor_first:
        return "landed outside the foam (hit the floor first)"
    if math.isnan(tracker.landed_s):
        return "never landed on the foam"
    x, y, _ = tracker.landing_m
    if not (0.0 <= x <= foam.length_m and abs(y) <= foam.width_m / 2):
        return f"landed outside the foam (at x = {x:.2f} m, y = {y:.2f} m)"
    return ""


class _EdgeCrossing:
    """When a point ``offset_m`` ahead (in x) of the base origin crosses the edge line x = 0 (s, interpolated)."""

    def __init__(self, offset_m: float) -> None:
        self._offset_m = offset_m
        self._previous_x: typing.Optional[float] = None
        self.time_s = NOT_MEASURED

    def update(self, steps: int, dt: float, base_x: float) -> bool:
        """Account for step number ``steps`` after which the base origin is at x = ``base_x``; True on crossing."""
        x = base_x + self._offset_m
        previous = self._previous_x
        crossed = x >= 0.0 and previous is not None and math.isnan(self.time_s)
        if crossed and previous is not None:
            self.time_s = (steps - 1 + -previous / (x - previous)) * dt
        self._previous_x = x
        return crossed


class LaunchTracker:
    """Follows one launch step by step: the foremost point crossing the edge (travel time), the base origin
    crossing it (going over: ``in_flight``), the first foam contact (``settling``), the hardest deceleration.

    Times are simulated seconds from the push, NaN until the event happens. ``world`` is the engine's launch world
    (:class:`LaunchWorld`): the tracker reads its base velocity and foam / floor contacts.
    """

    def __init__(self, world: "LaunchWorld", lead_m: float, phases: PhaseReporter, push: npt.ArrayLike) -> None:
        self._world = world
        self._push = np.asarray(push, dtype=np.float64)
        self.phases = phases
        self.edge_speed_mps = NOT_MEASURED
        self.floor_first = False
        self.front = _EdgeCrossing(lead_m)
        self.base = _EdgeCrossing(0.0)
        self.landed_s = NOT_MEASURED
        self.landing_m: typing.Tuple[float, ...] = (NOT_MEASURED,) * 3
        self.peak_deceleration_mps2 = 0.0
        self.edge_xy_m: typing.Tuple[float, float] = (0.0, 0.0)   # where the base origin crossed the edge line
        self._velocity: typing.Optional[typing.Tuple[float, ...]] = None

    @property
    def went_over(self) -> bool:
        """True once the base origin has crossed the edge line (the robot went over the edge)."""
        return not math.isnan(self.base.time_s)

    @property
    def settling_only(self) -> bool:
        """True once only the peak deceleration is left to watch per step (landed, after the crossings)."""
        return not math.isnan(self.landed_s) and self._velocity is not None

    @property
    def last_velocity(self) -> typing.Optional[typing.Tuple[float, ...]]:
        """The base velocity after the last step accounted for (m/s), or None before the robot went over."""
        return self._velocity

    def add_steps(self, peak_mps2: float, velocity: typing.Sequence[float]) -> None:
        """Account for steps :meth:`LaunchWorld.advance` took after the landing: their peak and last velocity."""
        self.peak_deceleration_mps2 = max(self.peak_deceleration_mps2, peak_mps2)
        self._velocity = tuple(velocity)

    @property
    def on_foam(self) -> bool:
        """True once the robot has landed, and its first landing was on the foam."""
        return not math.isnan(self.landed_s) and not self.floor_first

    def update(self, steps: int, dt: float, position: typing.Sequence[float]) -> None:
        """Account for step number ``steps`` (of ``dt`` s) after which the base origin is at ``position`` (3,), m."""
        if self.front.update(steps, dt, position[0]):
            self.edge_speed_mps = float(np.dot(self._world.velocity(), self._push))
        if math.isnan(self.base.time_s):
            if self.base.update(steps, dt, position[0]):
                self.edge_xy_m = (0.0, float(position[1]))
                self.phases.reach("in_flight")
            return
        velocity = tuple(self._world.velocity())   # plain floats: numpy's per-call cost exceeds a MuJoCo step
        if math.isnan(self.landed_s):
            on_foam, on_floor = self._world.touching()
            if on_foam or on_floor:
                self.floor_first = not on_foam
                self.landed_s, self.landing_m = steps * dt, tuple(float(v) for v in position)
                self.phases.reach("settling")
        if not math.isnan(self.landed_s) and self._velocity is not None:
            change = math.dist(velocity, self._velocity) / dt
            self.peak_deceleration_mps2 = max(self.peak_deceleration_mps2, change)
        self._velocity = velocity


class LaunchWorld:
    """What the launch loop (:func:`step_launch`) needs of an engine's world holding the twin: the robot's base
    pose and velocity, its first contacts, one step, the rest rule (the PyBullet and MuJoCo twins implement it)."""

    def pose(self) -> typing.Tuple[typing.Sequence[float], typing.Sequence[float]]:
        """The base origin (x, y, z) (m) and orientation (x, y, z, w) now."""
        raise NotImplementedError

    def velocity(self) -> typing.Sequence[float]:
        """The base origin's linear velocity (3,) in the world frame, m/s."""
        raise NotImplementedError

    def touching(self) -> typing.Tuple[bool, bool]:
        """``(on the foam, on the floor)``: whether the robot touches each now."""
        raise NotImplementedError

    def step(self) -> None:
        """Advance the world by one time step."""
        raise NotImplementedError

    def settled(self, steps: int) -> bool:
        """After step number ``steps``: True once the robot has stayed at rest for the trials' hold time."""
        raise NotImplementedError

    def advance(self, steps: int, dt: float, velocity: typing.Sequence[float]
                ) -> typing.Tuple[float, typing.Sequence[float]]:
        """Step ``steps`` times with nothing to watch but the base's velocity; return ``(largest change of the
        base velocity over one step / dt, m/s^2, the velocity after the last step)``, ``velocity`` the one before
        the first. :func:`step_launch` uses it once the robot has landed and the plate has stopped."""
        peak = 0.0
        for _ in range(steps):
            self.step()
            now = tuple(self.velocity())
            peak = max(peak, math.dist(now, velocity) / dt)
            velocity = now
        return peak, velocity

    def decide(self, remaining_s: float) -> typing.Optional[bool]:
        """The early decision now (True / False: the outcome is fixed upright / not upright; None: still open, or
        no early decision in this world), ``remaining_s`` before the time cap (:func:`decided_on_foam`).
        :func:`step_launch` asks only once the robot has landed on the foam and the plate has stopped: from then
        on only gravity and passive contacts act."""
        return None


class _BulletLaunchWorld(LaunchWorld):
    """:class:`LaunchWorld` of one PyBullet client holding the twin's bodies and the spawned robot."""

    def __init__(self, pybullet: types.ModuleType, client: int, robot: SpawnedRobot, foam_id: int, floor_id: int,
                 settings: LaunchTwinSettings, profile: typing.Optional[ProfileBody]) -> None:
        self._pybullet, self._client, self._robot = pybullet, client, robot
        self._body, self._foam, self._floor = robot.body_id, foam_id, floor_id
        self._rest = RestDetector(settings.trial, settings.physics.time_step_s)
        self._settings, self._profile = settings, profile
        self._energy: typing.Optional[EnergyMonitor] = None

    def pose(self) -> typing.Tuple[typing.Sequence[float], typing.Sequence[float]]:
        return self._pybullet.getBasePositionAndOrientation(self._body, physicsClientId=self._client)

    def velocity(self) -> typing.Sequence[float]:
        return self._pybullet.getBaseVelocity(self._body, physicsClientId=self._client)[0]

    def touching(self) -> typing.Tuple[bool, bool]:
        contacts, client = self._pybullet.getContactPoints, self._client
        if contacts(bodyA=self._body, bodyB=self._foam, physicsClientId=client):
            return True, False   # the tracker reads the floor only when the foam is not touched
        return False, bool(contacts(bodyA=self._body, bodyB=self._floor, physicsClientId=client))

    def step(self) -> None:
        self._robot.before_step()
        self._pybullet.stepSimulation(physicsClientId=self._client)

    def settled(self, steps: int) -> bool:
        return self._rest.settled(self._client, self._body, steps)

    def decide(self, remaining_s: float) -> typing.Optional[bool]:
        if self._energy is None:
            if not self._settings.trial.early_decision or self._robot.mount_spring is not None:
                return None   # the barriers hold for a rigid hull only, as in the trials
            self._energy = _bullet_energy_monitor(self._pybullet, self._client, self._robot, self._settings,
                                                  self._profile)
        com_xy_m = self._energy.com_xy_m()
        if hopeless_to_decide(com_xy_m, math.hypot(*self.velocity()), self._energy.radius_m, self._settings,
                              remaining_s):
            return None
        return decided_on_foam(self._energy, com_xy_m, self._settings, remaining_s)


#: Energy barriers and geometry of the early decision per robot + profile (the PyBullet twin spawns per launch).
_BASINS: typing.Dict[str, typing.Any] = {}


def foam_sink_m(settings: LaunchTwinSettings, mass_kg: float) -> float:
    """How far (m) a robot of ``mass_kg`` resting or rocking on the foam may sink into it: 3 m g / stiffness, its
    whole weight on one contact point, tripled for dynamic loads (as :func:`mujoco_trials.penetration_allowance_m`)."""
    return 3 * mass_kg * abs(settings.physics.gravity_mps2) / settings.twin.foam.contact_stiffness_npm


def clear_of_foam_edges(com_xy_m: typing.Sequence[float], radius_m: float, foam: FoamSpec) -> bool:
    """True when a hull of ``radius_m`` about a centre of mass at ``com_xy_m`` cannot reach the foam's edges or the
    ledge's wall (x = 0): the foam's flat top is then the only ground it can meet."""
    x, y = com_xy_m
    return radius_m < x < foam.length_m - radius_m and abs(y) < foam.width_m / 2 - radius_m


#: How long (s) a decided robot is assumed to keep rolling at most (:func:`decided_on_foam`): NOT a bound the
#: energy argument gives (a robot on free wheels loses little energy rolling); bench/verify_early_decision.py
#: --launches is the evidence that no outcome changes.
ROLL_HORIZON_S = 2.0


def hopeless_to_decide(com_xy_m: typing.Sequence[float], speed_mps: float, radius_m: float,
                       settings: LaunchTwinSettings, remaining_s: float) -> bool:
    """True when a robot at ``com_xy_m`` moving at ``speed_mps`` (its base) certainly fails
    :func:`decided_on_foam`'s edge test (the bound on its speed is at least about its speed now): the twins skip
    the energy computation then. Only a saving: skipping a decision never changes an outcome."""
    return not clear_of_foam_edges(com_xy_m, radius_m + speed_mps * min(remaining_s, ROLL_HORIZON_S),
                                   settings.twin.foam)


def decided_on_foam(energy: EnergyMonitor, com_xy_m: typing.Sequence[float], settings: LaunchTwinSettings,
                    remaining_s: float) -> typing.Optional[bool]:
    """The early decision of a landed robot (True / False / None), given its energy monitor (after ``decide``
    has read the state: ``energy_height_m``), its centre of mass (x, y) and the time left to the cap (s).

    The energy argument fixes the robot's orientation outcome on the foam's flat top, but a decided robot may
    still roll (on its wheels, or sliding) off the foam or back against the ledge, onto ground other than that
    top: the 5 cm drop to the floor or the ledge's wall can still turn it, so the argument no longer holds there
    (before issue 40 a chassis decided upright rolled off the foam's side 1.6 s after landing and the foam-contact
    rule judged it not upright; the rig's rule, :func:`rig_verdict`, counts it wherever it rests, but the drop is
    not in the barriers).
    Energy bounds its speed for ever by ``sqrt(2 g (E - lowest))`` (``lowest``: the lowest resting COM height of
    the decided outcome; the foam's sinking is left out here); the decision stands only if its hull cannot reach
    the foam's edges or the ledge at that speed within :data:`ROLL_HORIZON_S` (or the time left, if shorter)."""
    decision = energy.decide()
    if decision is None:
        return None
    excess_m = max(0.0, energy.energy_height_m - energy.basins.lowest_m(decision))
    travel_m = math.sqrt(2 * abs(settings.physics.gravity_mps2) * excess_m) * min(remaining_s, ROLL_HORIZON_S)
    return decision if clear_of_foam_edges(com_xy_m, energy.radius_m + travel_m, settings.twin.foam) else None


def _bullet_energy_monitor(pybullet, client, robot, settings, profile):
    """The early decision's :class:`~rollability_ros.core.sim.trials.EnergyMonitor` of a launched robot, its
    barriers on the foam top, lowered by :func:`foam_sink_m` (the map reused per robot + profile)."""
    from rollability_ros.core.sim.trials import EnergyMonitor
    model = settings.robot_model()
    key = hashlib.sha256(pickle.dumps((settings.robot, settings.urdf_robot, settings.physics, settings.trial,
                                       settings.twin.foam, profile), protocol=4)).hexdigest()
    mass_kg = sum(pybullet.getDynamicsInfo(robot.body_id, link, physicsClientId=client)[0]
                  for link in range(-1, pybullet.getNumJoints(robot.body_id, physicsClientId=client)))
    margin_m = settings.trial.early_decision_margin_m + foam_sink_m(settings, mass_kg)
    monitor = EnergyMonitor(client, model, robot, settings.physics.gravity_mps2, margin_m,
                            ground_z_m=settings.twin.foam.thickness_m, basins=_BASINS.get(key))
    _BASINS[key] = monitor.basins
    while len(_BASINS) > 8:
        del _BASINS[next(iter(_BASINS))]
    return monitor


def step_launch(world: LaunchWorld, plate: LaunchPlate, tracker: LaunchTracker, settings: LaunchTwinSettings,
                on_pose: typing.Optional[PoseCallback], speed_mps: float, stroke_m: float = math.inf,
                until_edge: bool = False) -> typing.Tuple[int, bool, typing.Optional[bool]]:
    """Step ``world`` (a :class:`LaunchWorld`) until the robot is at rest or the trials' time cap, driving ``plate``
    at ``speed_mps`` until it has travelled ``stroke_m`` (the cylinder's stroke; inf: push-through), the robot goes
    over the edge or the plate reaches it; return ``(steps, settled, decision)``. ``until_edge``: stop as soon as
    the robot's foremost point crosses the edge line (the gate's reading is then known: the speed solve of
    :func:`launch_drive`). Every twin runs its launches through this loop (the launch rules live here and in
    :class:`LaunchTracker`).

    Early decision (``trial.early_decision``): once the robot has landed on the foam and the plate has stopped,
    only gravity and passive contacts act on it, so the energy argument of
    :mod:`~rollability_ros.core.sim.early_decision` applies with the foam's top as the ground (barriers lowered by
    the foam's sinking, :func:`foam_sink_m`, as long as the robot cannot reach the foam's edges or the ledge,
    :func:`clear_of_foam_edges`, for as far as its energy can still carry it, :func:`decided_on_foam`). Every
    ``check_interval_steps`` the world's :meth:`LaunchWorld.decide` may end the launch with its outcome
    (``decision`` True / False; None when it ran to rest or the cap)."""
    dt = settings.physics.time_step_s
    cap = round(settings.trial.time_cap_s / dt)
    pose_every = max(1, round(1.0 / (settings.twin.pose_rate_hz * dt)))
    position, orientation = world.pose()
    tracker.update(0, dt, position)
    tracker.phases.reach("fired")
    if on_pose is not None:
        on_pose(0.0, position, orientation)
    steps = 0
    settled = False
    plate_started = False
    decision = None
    interval = settings.trial.check_interval_steps
    while steps < cap and not settled:
        velocity = tracker.last_velocity   # not None once settling_only
        if on_pose is None and tracker.settling_only and velocity is not None and not plate.driving:
            # landed, plate stopped: only the impact's peak is watched per step until the next look
            count = min(interval - steps % interval, cap - steps)
            tracker.add_steps(*world.advance(count, dt, velocity))
            steps += count
        else:
            steps = _one_step(world, plate, tracker, on_pose, speed_mps, steps, dt, pose_every, plate_started,
                              stroke_m)
            plate_started = True
            if until_edge and not math.isnan(tracker.front.time_s):
                break
        if steps % interval:   # the rest rule and the decision look every check_interval_steps only
            continue
        settled = world.settled(steps)
        if not settled and not plate.driving and tracker.on_foam:
            decision = world.decide((cap - steps) * dt)
            settled = decision is not None
    tracker.phases.reach("classifying")
    return steps, settled, decision


def _one_step(world, plate, tracker, on_pose, speed_mps, steps, dt, pose_every, plate_started, stroke_m):
    """One step of :func:`step_launch` with everything watched; returns the new step count."""
    if plate.driving or not plate_started:
        plate.drive(speed_mps, (steps + 1) * dt)
    world.step()
    steps += 1
    position, orientation = world.pose()
    tracker.update(steps, dt, position)
    if plate.driving and (not math.isnan(tracker.base.time_s) or plate.reached_edge() or plate.travel_m() >= stroke_m):
        plate.stop()
    if on_pose is not None and steps % pose_every == 0:
        on_pose(steps * dt, position, orientation)
    return steps
