"""The launch twin of :mod:`rollability_ros.core.sim.launch` in MuJoCo (``sim.engine: mujoco``).

The same launch: ledge, push plate over the whole stroke, foam pad, floor; the same placement
(:func:`~rollability_ros.core.sim.launch.placement.launcher_start_xy`,
:func:`~rollability_ros.core.sim.launch.placement.plate_placement`), scatter draws, launch loop
(:func:`~rollability_ros.core.sim.launch.loop.step_launch`), event tracking
(:class:`~rollability_ros.core.sim.launch.loop.LaunchTracker`), landing and invalid-launch rules
(:func:`~rollability_ros.core.sim.launch.loop.invalid_reason`) and result; only the world differs. The robot is
the model of :mod:`~rollability_ros.core.sim.mujoco_trials` (the URDF PyBullet loads, profile hull as a mesh geom,
free root joint). A :class:`MujocoLaunchTwin` is compiled once per robot + profile + settings and each launch
resets its data, so launches of one candidate do not pay for a model build (a per-process cache,
:func:`simulate_launch`, keeps the last few).

World (metres; the frame of :mod:`~rollability_ros.core.sim.launch`)
    the floor: a plane at z = 0; the foam: its top, a plane at z = ``foam.thickness_m`` (MuJoCo's plane contacts
    cost a third of its box contacts; a robot touching that plane outside the foam's extent counts as hitting the
    floor first, an invalid launch as in the PyBullet twin, and one that later rolls off the foam's 2.5 x 3 m stays
    on its level: a known difference); the ledge: a box whose top is the launcher's base
    plate, on a mocap body moved to the condition's height before each launch (the box reaches below the floor);
    the push plate: a box on a slide joint whose frame is a mocap body placed behind the robot before each launch
    (push direction and plate face as in the PyBullet twin). Contact filtering: the plate touches only the robot.
Contact values (MuJoCo takes the larger of two geoms' friction; ``config/sim.yaml`` and the twin's files)
    robot on the ledge and floor: the trials' mapping (:func:`~rollability_ros.core.sim.mujoco_trials.set_geom_contact`:
    the robot's geoms carry the effective robot-ground values, ledge and floor zeros); the wheels' friction is
    times ``wheel_friction_left_factor`` / ``_right_factor``, their rolling friction is each wheel's own
    (:func:`~rollability_ros.core.sim.launch.settings.wheel_rolling_friction_m`: the Mecanum wheels'
    ``wheel_rolling_friction``, or a URDF robot's ``wheel_rolling_resistance`` x the wheel's radius) x the ground's
    friction (Bullet's combination), and, when the twin gives them its Mecanum wheels
    (:func:`~rollability_ros.core.sim.launch.settings.mecanum_wheels`: the chassis), joint ``frictionloss`` =
    ``wheel_drag_torque_nm``; otherwise (a URDF robot) the robot's own joint drag, as in the trials. The launcher's
    sizes are the PyBullet twin's (derived from the robot where configured 0: ``sized_for_robot``).
    Foam: a geom of higher priority, so its values make the contact with the body: friction = the robot's
    ``lateral_friction`` x ``foam.lateral_friction``, rolling = the robot body's rolling friction on the foam
    (Bullet's ``a.rolling b.friction + b.rolling a.friction``); each wheel meets the foam by an explicit contact
    pair carrying Bullet's combination of that wheel's own values (its friction with the left / right factor, its
    own rolling friction) with the foam's, and the foam's spring; and a
    direct spring-damper (``solref`` = -stiffness / m, -damping / m with m the robot's mass: Bullet's per-contact
    N/m and N s/m as an acceleration per metre of one contact carrying the whole robot), at least critically
    damped (a lighter damping left a landed chassis rocking for ever, as in the MuJoCo trials). MuJoCo steps in
    substeps of the twin's step that resolve that spring (:func:`foam_substeps`, :data:`FOAM_OMEGA_SUBSTEP`: at
    one step of 1/240 s the shipped foam threw a chassis landing flat back at 0.45 x its impact speed, a numerical
    rebound; resolved, 0.14, PyBullet's 0.05-0.10); a foam stiffer than :data:`FOAM_MAX_SUBSTEPS` resolve is capped
    at :data:`FOAM_MAX_OMEGA_DT` per twin step. A launch that still goes unstable raises ``RuntimeError``.
Friction cone: elliptic (Coulomb's isotropic friction; Bullet's friction follows the sliding direction), not
    MuJoCo's default pyramid.
    Plate: friction 0.3 x the robot's ``lateral_friction`` (Bullet's product), the trials' contact spring.
Not represented (known differences, measured by ``rollability evaluate --engines`` and ``bench/bench_engines.py``)
    restitution (as in the MuJoCo trials: contacts are critically damped springs; the foam's is as configured),
    the Mecanum wheels' low side friction (MuJoCo friction is isotropic), and the plate's velocity control is an
    implicit damper towards the target speed whose gain keeps the force within ``max_force_n``
    (:class:`_MujocoPlate`) rather than Bullet's velocity constraint.
"""
import collections
import dataclasses
import hashlib
import math
import pickle
import typing

import numpy as np
import numpy.typing as npt

from rollability_ros.core.optional import require
from rollability_ros.core.profile import DesignSources
from rollability_ros.core.records import LaunchCondition
from rollability_ros.core.robots import ProfileBody
from rollability_ros.core.sim.early_decision import hull_vertices
from rollability_ros.core.sim.launch.contract import LaunchDrive, LaunchEngine, LaunchWorld
from rollability_ros.core.sim.launch.decision import decided_on_foam, foam_sink_m, hopeless_to_decide
from rollability_ros.core.sim.launch.drive import launch_drive
from rollability_ros.core.sim.launch.loop import LaunchTracker, PhaseReporter, launch_result, rig_verdict, step_launch
from rollability_ros.core.sim.launch.placement import check_fits_launcher, launch_plan, launcher_start_xy, plate_placement
from rollability_ros.core.sim.launch.results import LaunchResult, PhaseCallback, PoseCallback
from rollability_ros.core.sim.launch.settings import (LaunchTwinSettings, PushPlateSpec, mecanum_wheels,
                                                      wheel_rolling_friction_m)
from rollability_ros.core.sim.mujoco_trials import (MujocoEnergyMonitor, effective_contact, geom_points, pose_speeds,
                                                    robot_spec, root_tilt_deg, set_geom_contact, wheel_bodies)


#: Half-height of the ledge's box (m): it reaches from the base plate to below the floor at any condition height.
LEDGE_HALF_HEIGHT_M = 5.0

#: The push plate's own friction coefficient (Bullet multiplies it with the robot's), as in the PyBullet twin.
PLATE_FRICTION = 0.3

#: Time constant of the plate-robot contact spring, steps (critically damped): a softer one (the trials' 0.02 s)
#: was compressed by the plate's ramp and threw the robot off the plate faster than the launch speed.
PLATE_TIME_CONSTANT_STEPS = 2

PLATE_DAMPING_RATIO = 3.0

#: Foam spring per unit robot mass resolved by the MuJoCo twin's substep, as natural frequency x substep: the twin
#: steps MuJoCo in ``ceil(omega dt / FOAM_OMEGA_SUBSTEP)`` substeps per twin step (:func:`foam_substeps`). Measured
#: (a chassis dropped flat on the shipped foam at 4 m/s, test/core/test_twin_engine_fidelity.py): at the twin's 1/240 s
#: (omega dt 0.56, one substep) the critically damped spring overshoots within the step and throws the chassis back
#: at 0.45 x its impact speed; at 1/480 s 0.15, at 1/960 s 0.14 (converged); PyBullet's foam 0.05-0.10.
FOAM_OMEGA_SUBSTEP = 0.3

#: Most substeps per twin step (a MuJoCo launch's cost grows with them).
FOAM_MAX_SUBSTEPS = 4

#: Stiffest foam spring the MuJoCo twin takes per unit robot mass, as natural frequency x twin step: what
#: FOAM_MAX_SUBSTEPS resolve (1.2: 4.6 x the shipped foam on the chassis; the robust draws reach 2 x). A stiffer
#: foam acts as this one (before the substeps the cap was 0.6 at one step, where a spring already rebounded).
FOAM_MAX_OMEGA_DT = FOAM_OMEGA_SUBSTEP * FOAM_MAX_SUBSTEPS

#: Collision bits: the robot touches everything, the plate only the robot, the static world only the robot; the
#: foam only the robot's geoms that carry its bit (not the wheels: they meet the foam by explicit pairs).
ROBOT_BITS, PLATE_BITS, STATIC_BITS, FOAM_BITS = (1, 3), (2, 2), (4, 1), (4, 8)

#: Compiled twins kept per process (a generation's candidates in turn; each holds one model).
CACHE_SIZE = 4

def foam_substeps(stiffness_per_kg: float, time_step_s: float) -> int:
    """MuJoCo steps per twin step of ``time_step_s`` that resolve a foam spring of ``stiffness_per_kg`` (N/m per kg
    of robot): omega x substep at most :data:`FOAM_OMEGA_SUBSTEP`, at most :data:`FOAM_MAX_SUBSTEPS`."""
    omega_dt = math.sqrt(max(stiffness_per_kg, 0.0)) * time_step_s
    return max(1, min(FOAM_MAX_SUBSTEPS, math.ceil(omega_dt / FOAM_OMEGA_SUBSTEP - 1e-9)))

def _quat_wxyz(yaw_rad):
    return [math.cos(yaw_rad / 2), 0.0, 0.0, math.sin(yaw_rad / 2)]

class MujocoLaunchTwin(LaunchWorld):
    """One robot + profile on the MuJoCo launch twin (module docstring): ``launch(...)`` -> ``LaunchResult``.

    Its robot is the MuJoCo trials' (:func:`~rollability_ros.core.sim.mujoco_trials.robot_spec`) and its tilt their
    rule (:func:`~rollability_ros.core.sim.mujoco_trials.root_tilt_deg`); the surface the early decision's energy
    monitor judges against (``ground_geom``) is the ledge (the foam's top is its ``ground_z_m``).
    """

    def __init__(self, settings: LaunchTwinSettings, profile: typing.Optional[ProfileBody]) -> None:
        self.mujoco = mujoco = require("mujoco", feature="the MuJoCo launch twin")
        self.settings, self.physics, self.robot_model = settings, settings.physics, settings.robot_model()
        self.profile = profile
        spec, root = robot_spec(self.robot_model, profile, settings.physics)
        # Coulomb's friction is isotropic: MuJoCo's elliptic cone is it, its default pyramid allows less friction
        # off its axes (MuJoCo documentation, "Computation", friction cones); Bullet's two friction directions
        # follow the sliding velocity (btSequentialImpulseConstraintSolver), isotropic too (docs/optimization.md,
        # "The engines' disagreement on the bare robot")
        spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
        wheel_names = set(self.robot_model.wheel_link_names())
        wheel_specs = [geom for body in spec.bodies if body.name in wheel_names for geom in body.geoms]
        for geom in spec.geoms:
            geom.contype, geom.conaffinity = ROBOT_BITS
            if not any(geom is wheel for wheel in wheel_specs):
                geom.contype |= FOAM_BITS[1]   # the body meets the foam by the foam geom's values
        for index, geom in enumerate(wheel_specs):   # a wheel meets it by its own pair (module docstring)
            geom.name = geom.name or f"wheel_geom_{index}"
            pair = spec.add_pair()
            pair.geomname1, pair.geomname2, pair.condim = geom.name, "foam", 6
        self._add_static_world(spec)
        self._add_plate(spec)
        self.model = model = spec.compile()
        self.data = mujoco.MjData(model)
        self.root = model.body(root.name).id
        self.wheels = wheel_bodies(model, self.robot_model)
        self.floor_geom, self.foam_geom, self.ledge_geom = (model.geom(name).id for name in ("floor", "foam", "ledge"))
        self.plate_geom = model.geom("plate").id
        self.ledge_mocap = model.body("ledge").mocapid[0]
        self.plate_mocap = model.body("plate_frame").mocapid[0]
        self.plate_qpos = model.jnt_qposadr[model.joint("plate_slide").id]
        self.plate_dof = model.jnt_dofadr[model.joint("plate_slide").id]
        self.robot_geoms = [g for g in range(model.ngeom) if model.body_rootid[model.geom_bodyid[g]] == self.root]
        self.wheel_geoms = {body: [g for g in self.robot_geoms if model.geom_bodyid[g] == body]
                            for body in self.wheels}
        radius_of = dict(zip(self.robot_model.wheel_link_names(), self.robot_model.wheel_radii_m()))
        self.wheel_radius_m = {body: radius_of[model.body(body).name] for body in self.wheels}
        self._robot_geom_set = set(self.robot_geoms)
        up = np.asarray(self.robot_model.up_axis_in_root(), dtype=np.float64)
        self.up_in_root = up / np.linalg.norm(up)
        self.ground_geom = self.ledge_geom
        self.mass_kg = float(model.body_subtreemass[self.root])
        self._set_contacts()
        self._plate: typing.Optional[_MujocoPlate] = None   # set by each launch
        self._local_points: typing.Optional[typing.List[typing.Tuple[int, np.ndarray]]] = None
        self._previous_pose, self._rest_since = None, None
        self._profile = profile
        self._build_ipos_z = float(model.body_ipos[self.root][2])   # retarget moves the COM from here, absolutely
        self._build_com_offset_z_m = settings.robot.com_offset_z_m
        self.energy: typing.Optional[MujocoEnergyMonitor] = None
        self.attach_energy()

    def _add_static_world(self, spec: typing.Any) -> None:
        """The floor, the foam's top and the ledge (on its mocap body) in ``spec`` (an ``MjSpec``; module docstring)."""
        mujoco, physics, options = self.mujoco, self.settings.physics, self.settings.twin
        world = spec.worldbody
        floor = world.add_geom()
        floor.name, floor.type, floor.size = "floor", mujoco.mjtGeom.mjGEOM_PLANE, [0.0, 0.0, 1.0]
        foam = world.add_geom()   # the foam's top as a plane (FOAM_AS_PLANE)
        foam.name, foam.type = "foam", mujoco.mjtGeom.mjGEOM_PLANE
        foam.size = [options.foam.length_m / 2, options.foam.width_m / 2, 1.0]
        foam.pos = [options.foam.length_m / 2, 0.0, options.foam.thickness_m]
        ledge_body = world.add_body()
        ledge_body.name, ledge_body.mocap = "ledge", True
        ledge = ledge_body.add_geom()
        ledge.name, ledge.type = "ledge", mujoco.mjtGeom.mjGEOM_BOX
        launcher = options.launcher
        ledge.size = [launcher.ledge_depth_m / 2, launcher.ledge_width_m / 2, LEDGE_HALF_HEIGHT_M]
        for geom in (floor, ledge):
            set_geom_contact(geom, physics, ground=True)
        for geom in (floor, ledge):
            geom.contype, geom.conaffinity = STATIC_BITS
        foam.contype, foam.conaffinity = FOAM_BITS

    def _add_plate(self, spec: typing.Any) -> None:
        """The push plate in ``spec``: a box on a slide joint whose frame is a mocap body (module docstring)."""
        mujoco, physics, options = self.mujoco, self.settings.physics, self.settings.twin
        frame = spec.worldbody.add_body()
        frame.name, frame.mocap = "plate_frame", True
        plate_body = frame.add_body()
        plate_body.name = "plate"
        plate_body.mass = options.plate.mass_kg
        plate_body.inertia = [1e-4, 1e-4, 1e-4]
        slide = plate_body.add_joint()
        slide.name, slide.type, slide.axis = "plate_slide", mujoco.mjtJoint.mjJNT_SLIDE, [1.0, 0.0, 0.0]
        plate = plate_body.add_geom()
        plate.name, plate.type = "plate", mujoco.mjtGeom.mjGEOM_BOX
        spec_plate = options.plate
        plate.size = [spec_plate.thickness_m / 2, spec_plate.width_m / 2, spec_plate.height_m / 2]
        plate.quat = _quat_wxyz(math.radians(spec_plate.yaw_bias_deg))
        plate.mass = options.plate.mass_kg
        set_geom_contact(plate, physics)
        plate.friction = [PLATE_FRICTION * physics.lateral_friction, 0.0, 0.0]
        plate.condim = 3
        plate.priority = 1          # its friction and its stiff spring make the plate-robot contact
        plate.solref = [PLATE_TIME_CONSTANT_STEPS * physics.time_step_s, PLATE_DAMPING_RATIO]
        plate.contype, plate.conaffinity = PLATE_BITS

    def attach_energy(self) -> None:
        """The early decision's barriers for the current settings (none when ``trial.early_decision`` is off or
        the profile is compliant: barriers need a rigid hull); valid until a retarget changes the foam or COM."""
        settings, options = self.settings, self.settings.twin
        compliant = self._profile is not None and self.robot_model.profile_mount.compliant
        self.energy = MujocoEnergyMonitor(
            self, settings.trial.early_decision_margin_m, sink_m=foam_sink_m(settings, self.mass_kg),
            ground_z_m=options.foam.thickness_m) if settings.trial.early_decision and not compliant else None
        self._energy_foam, self._energy_com_offset_z_m = options.foam, settings.robot.com_offset_z_m
        self._energy_valid = True

    def _set_contacts(self):
        """The wheels' and the foam's contact values (module docstring) on the compiled model."""
        model, data, options, physics = self.model, self.data, self.settings.twin, self.physics
        lateral, spinning, rolling, _ = effective_contact(physics)
        ground_lateral = physics.ground_contact()["lateralFriction"]
        self.mujoco.mj_resetData(model, data)
        data.qpos[0:7] = [0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0]
        self.mujoco.mj_forward(model, data)
        root_rotation = data.xmat[self.root].reshape(3, 3)
        for geom in self.robot_geoms:   # the robot-ground values of sim.contact_model (robot_spec's, redone per draw)
            model.geom_friction[geom] = [lateral, spinning, rolling]
        mecanum = mecanum_wheels(self.settings)
        bodies = list(self.wheel_geoms)
        own_rolling = dict(zip(bodies, wheel_rolling_friction_m(self.settings,
                                                                [self.wheel_radius_m[body] for body in bodies])))
        factors = {}
        for body, geoms in self.wheel_geoms.items():
            left = float((data.xpos[body] - data.xpos[self.root]) @ root_rotation[:, 1]) >= 0.0
            factor = factors[body] = options.wheel_friction_left_factor if left else options.wheel_friction_right_factor
            for geom in geoms:   # the wheel's own rolling friction x the ground's friction: Bullet's combination
                model.geom_friction[geom][0] = lateral * factor
                model.geom_friction[geom][2] = own_rolling[body] * ground_lateral
            for joint in range(model.njnt):
                if mecanum and model.jnt_bodyid[joint] == body:
                    model.dof_frictionloss[model.jnt_dofadr[joint]] = options.wheel_drag_torque_nm
        # the base plate's unknown rolling resistance (launcher.ledge_rolling_friction): MuJoCo takes the larger
        # of two geoms' values, so the ledge carries the wheels' rolling friction plus Bullet's ledge.rolling x
        # wheel.lateral (0 = the trials' mapping: the ledge's zeros)
        ledge_rolling = options.launcher.ledge_rolling_friction
        wheel_rolling = max(own_rolling.values(), default=0.0) * ground_lateral   # one ledge geom: the largest wheel's
        model.geom_friction[self.ledge_geom] = [
            0.0, 0.0, wheel_rolling + ledge_rolling * physics.lateral_friction if ledge_rolling else 0.0]
        contact = physics.body_contact()
        foam = options.foam
        model.geom_priority[self.foam_geom] = 1
        model.geom_condim[self.foam_geom] = 6
        model.geom_friction[self.foam_geom] = [
            physics.lateral_friction * foam.lateral_friction, spinning,
            contact["rollingFriction"] * foam.lateral_friction + foam.rolling_friction * physics.lateral_friction]
        # the foam's spring is resolved in substeps (FOAM_OMEGA_SUBSTEP), at most FOAM_MAX_SUBSTEPS of them: a
        # stiffer spring is capped at what they resolve (unresolved it rebounds, and at omega dt 0.76 blew up)
        stiffness = min(foam.contact_stiffness_npm / self.mass_kg, (FOAM_MAX_OMEGA_DT / physics.time_step_s) ** 2)
        self.substeps = foam_substeps(stiffness, physics.time_step_s)
        model.opt.timestep = physics.time_step_s / self.substeps
        # at least critically damped: the configured 150 N s/m (damping ratio 0.48 on the chassis) left a landed
        # chassis rocking on the foam in a limit cycle at 1/240 s that never passed the rest rule
        model.geom_solref[self.foam_geom] = [-stiffness, -max(foam.contact_damping_nspm / self.mass_kg,
                                                              2 * math.sqrt(stiffness))]
        model.geom_solimp[self.foam_geom] = [0.99, 0.99, 0.001, 0.5, 2.0]
        # each wheel on the foam: Bullet's combination of the wheel's own values with the foam's (friction product,
        # rolling wheel.rolling x foam.friction + foam.rolling x wheel.friction), the foam's spring
        for pair in range(model.npair):   # MuJoCo may store the foam first
            wheel = model.pair_geom2[pair] if model.pair_geom1[pair] == self.foam_geom else model.pair_geom1[pair]
            body = int(model.geom_bodyid[wheel])
            wheel_lateral = physics.lateral_friction * factors[body]
            roll = own_rolling[body] * foam.lateral_friction + foam.rolling_friction * wheel_lateral
            model.pair_friction[pair] = [wheel_lateral * foam.lateral_friction] * 2 + [spinning, roll, roll]
            model.pair_solref[pair] = model.geom_solref[self.foam_geom]
            model.pair_solimp[pair] = model.geom_solimp[self.foam_geom]

    def retarget(self, settings: LaunchTwinSettings) -> None:
        """Take a robustness draw's ``settings`` (:mod:`~rollability_ros.core.sim.robustness`) without a new
        model: the contact reading (``sim.contact_model``), the foam's stiffness, damping, restitution, friction and
        rolling friction, the Mecanum wheels' drag and the base plate's rolling friction go into the compiled
        model's contact values and joint friction, the chassis's drawn centre-of-mass height moves the base body's
        centre of mass (the chassis's share of the fused base; its inertia about the centre of mass kept), and the
        disturbance fields do not touch a launch. The early decision is off for a launch whose centre of mass or
        foam differs from the ones its barriers were built for (they depend on both)."""
        if settings == self.settings:
            return
        old = self.settings
        if not settings.urdf_robot.selected and settings.robot.com_offset_z_m != old.robot.com_offset_z_m:
            share = settings.robot.body_mass_kg / float(self.model.body_mass[self.root])
            # from the build's value, not the last draw's: the model of a draw never depends on the draws before it
            self.model.body_ipos[self.root][2] = self._build_ipos_z + (
                settings.robot.com_offset_z_m - self._build_com_offset_z_m) * share
            self.mujoco.mj_setConst(self.model, self.data)   # the constants compiled from the mass properties
        self.settings, self.physics = settings, settings.physics
        self._set_contacts()
        self._energy_valid = (self.settings.twin.foam == self._energy_foam and
                              self.settings.robot.com_offset_z_m == self._energy_com_offset_z_m)

    # -- the placement ------------------------------------------------------------------------------------------
    def robot_points(self) -> np.ndarray:
        """The world points (n, 3) whose hull is the robot's collision geometry now (m)."""
        data = self.data
        if self._local_points is None:   # each geom's hull vertices in its own frame (fixed), computed once
            mujoco, model = self.mujoco, self.model
            self._local_points = [(geom, hull_vertices(local)) for geom in self.robot_geoms
                                  for local in [geom_points(mujoco, model, geom)] if local is not None]
        return np.vstack([local @ data.geom_xmat[geom].reshape(3, 3).T + data.geom_xpos[geom]
                          for geom, local in self._local_points])

    def place(self, orientation_xyzw: typing.Sequence[float], clearance_m: float,
              xy_m: typing.Sequence[float] = (0.0, 0.0), ground_z_m: float = 1.0) -> None:
        """Reset the data and put the robot at rest with its lowest point ``clearance_m`` above z = ``ground_z_m``
        at ``xy_m`` (base origin, (x, y) m); ``orientation_xyzw`` the base's (x, y, z, w); the default holds it in the
        air (the energy monitor's geometry)."""
        mujoco, model, data = self.mujoco, self.model, self.data
        mujoco.mj_resetData(model, data)
        x, y, z, w = orientation_xyzw
        data.qpos[0:7] = [xy_m[0], xy_m[1], 0.0, w, x, y, z]
        data.mocap_pos[self.ledge_mocap] = [0.0, 0.0, -10.0]
        data.mocap_pos[self.plate_mocap] = [0.0, 0.0, -20.0]
        mujoco.mj_forward(model, data)
        data.qpos[2] += ground_z_m + clearance_m - float(self.robot_points()[:, 2].min())
        mujoco.mj_forward(model, data)

    # -- LaunchWorld --------------------------------------------------------------------------------------------
    def pose(self) -> typing.Tuple[typing.Sequence[float], typing.Sequence[float]]:
        q = self.data.qpos[0:7].tolist()
        return q[0:3], (q[4], q[5], q[6], q[3])

    def velocity(self) -> typing.Sequence[float]:
        return self.data.qvel[0:3].tolist()

    def touching(self) -> typing.Tuple[bool, bool]:
        if not self.data.ncon:   # in flight
            return False, False
        contact, robot, foam = self.data.contact, self._robot_geom_set, self.settings.twin.foam
        on_foam = on_floor = False
        for a, b, (x, y, _) in zip(contact.geom1.tolist(), contact.geom2.tolist(), contact.pos.tolist()):
            other = b if a in robot else a if b in robot else None
            if other == self.foam_geom:   # the plane beyond the foam's extent stands for the floor below it
                inside = 0.0 <= x <= foam.length_m and abs(y) <= foam.width_m / 2
                on_foam, on_floor = on_foam or inside, on_floor or not inside
            elif other == self.floor_geom:
                on_floor = True
        return on_foam, on_floor

    def step(self) -> None:
        plate = self._launch_plate()
        for _ in range(self.substeps):
            if plate.driving or not plate.at_rest:
                self.data.qfrc_applied[self.plate_dof] = plate.force()
            self.mujoco.mj_step(self.model, self.data)

    def _launch_plate(self) -> "_MujocoPlate":
        """The plate of the launch under way (the world steps only within :meth:`launch`)."""
        if self._plate is None:
            raise RuntimeError("the MuJoCo launch twin steps only within a launch (no push plate placed yet)")
        return self._plate

    def advance(self, steps: int, dt: float, velocity: typing.Sequence[float]
                ) -> typing.Tuple[float, typing.Sequence[float]]:
        # LaunchWorld.advance without the per-step calls: the plate is at rest (force 0, its damping holds it)
        mujoco, model, data = self.mujoco, self.model, self.data
        plate, qvel, step, substeps = self._launch_plate(), data.qvel, mujoco.mj_step, range(self.substeps)
        peak = 0.0
        px, py, pz = velocity
        for _ in range(steps):
            for _ in substeps:
                if not plate.at_rest:
                    data.qfrc_applied[self.plate_dof] = plate.force()
                step(model, data)
            vx, vy, vz = qvel[0:3].tolist()
            change = (vx - px) * (vx - px) + (vy - py) * (vy - py) + (vz - pz) * (vz - pz)
            peak = change if change > peak else peak
            px, py, pz = vx, vy, vz
        return math.sqrt(peak) / dt, (px, py, pz)

    def settled(self, steps: int) -> bool:
        trial = self.settings.trial
        if steps % trial.check_interval_steps:
            return False
        pose = self.data.qpos[0:7].copy()
        previous, self._previous_pose = self._previous_pose, pose
        if previous is None:
            return False
        linear, angular = pose_speeds(previous, pose, trial.check_interval_steps * self.physics.time_step_s)
        if linear < trial.rest_linear_speed_mps and angular < math.radians(trial.rest_angular_speed_dps):
            self._rest_since = steps if self._rest_since is None else self._rest_since
            return steps - self._rest_since >= round(trial.rest_hold_s / self.physics.time_step_s)
        self._rest_since = None
        return False

    def decide(self, remaining_s: float) -> typing.Optional[bool]:
        energy = self.energy
        if energy is None or not self._energy_valid:
            return None
        mujoco, model, data = self.mujoco, self.model, self.data
        vx, vy, vz = data.qvel[0:3].tolist()
        if hopeless_to_decide(data.qpos[0:2].tolist(), math.sqrt(vx * vx + vy * vy + vz * vz), energy.radius_m,
                              self.settings, remaining_s):
            return None
        # the monitor reads the COM and the mass matrix of the current state (mj_step left those of the last)
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        mujoco.mj_makeM(model, data)
        return decided_on_foam(energy, data.subtree_com[self.root][:2].tolist(), self.settings, remaining_s)

    # -- one launch ---------------------------------------------------------------------------------------------
    def launch(self, condition: LaunchCondition, seed: int, on_phase: typing.Optional[PhaseCallback] = None,
               on_pose: typing.Optional[PoseCallback] = None, *, drive: typing.Optional[LaunchDrive] = None,
               until_edge: bool = False) -> LaunchResult:
        """One launch of ``condition`` with ``seed`` and the cylinder's ``drive``
        (:func:`~rollability_ros.core.sim.launch.twin.simulate_launch`'s rules; ``until_edge``: stop once the
        foremost point crosses the edge); returns its :class:`~rollability_ros.core.sim.launch.results.LaunchResult`."""
        mujoco, model, data, settings = self.mujoco, self.model, self.data, self.settings
        options = settings.twin
        if drive is None:   # the speed solve launches on the cached twins (this one too): back to these settings
            drive = launch_drive(settings, condition.speed_mps)
            self.retarget(settings)
        speed_mps, angle_deg, push = launch_plan(condition, seed, options)
        plate_z = options.foam.thickness_m + condition.height_m
        orientation = (0.0, 0.0, math.sin(math.radians(angle_deg) / 2), math.cos(math.radians(angle_deg) / 2))
        self.place(orientation, options.launcher.start_clearance_m, (0.0, 0.0), plate_z)
        lead_m = float(self.robot_points()[:, 0].max()) - float(data.qpos[0])
        self.place(orientation, options.launcher.start_clearance_m, launcher_start_xy(lead_m, push, options.launcher),
                   plate_z)
        points = self.robot_points()
        check_fits_launcher(points.min(axis=0), points.max(axis=0), options.launcher)
        placement = plate_placement(float((points @ push).min()), data.qpos[0:3], push, options.plate, plate_z)
        data.mocap_pos[self.ledge_mocap] = [-options.launcher.ledge_depth_m / 2, 0.0, plate_z - LEDGE_HALF_HEIGHT_M]
        data.mocap_pos[self.plate_mocap] = placement.centre_m
        data.mocap_quat[self.plate_mocap] = _quat_wxyz(placement.yaw_rad)
        mujoco.mj_forward(model, data)
        gap = min(mujoco.mj_geomDistance(model, data, self.plate_geom, geom, 1.0, None) for geom in self.robot_geoms)
        data.qpos[self.plate_qpos] = max(0.0, gap - 0.001)
        mujoco.mj_forward(model, data)
        self._previous_pose, self._rest_since = None, None
        plate = self._plate = _MujocoPlate(self, drive.plate_spec(options.plate), push, placement.face_x_m)
        tracker = LaunchTracker(self, lead_m, PhaseReporter(on_phase), push)
        unstable = mujoco.mjtWarning.mjWARN_BADQACC
        data.warning[unstable].number = 0
        steps, settled, decision = step_launch(self, plate, tracker, settings, on_pose,
                                               drive.plate_speed_mps(speed_mps), drive.stroke_m, until_edge)
        if data.warning[unstable].number:
            raise RuntimeError(f"the MuJoCo launch twin went unstable (bad accelerations, MuJoCo reset the state) "
                               f"in {condition} with seed {seed}; foam {options.foam}")
        mujoco.mj_forward(model, data)
        tilt = self.tilt_deg()
        upright = rig_verdict(tilt, self.wheels_down(), self.robot_model) if decision is None else decision
        position, final_orientation = self.pose()
        return launch_result(tracker, settings, (steps, settled, decision), (upright, tilt, final_orientation),
                             (speed_mps, angle_deg), seed, position, drive.plate_speed_mps(speed_mps))

    def tilt_deg(self) -> float:
        """Angle between the robot's up axis and world +z now, degrees (the MuJoCo trials' rule)."""
        return root_tilt_deg(self.data.xmat[self.root], self.up_in_root)

    def wheels_down(self) -> int:
        """How many wheels are within the robot's ``contact_tolerance_m`` of the pad, the floor or the ledge: the
        wheels it stands on, wherever (:func:`~rollability_ros.core.sim.launch.loop.rig_verdict`)."""
        mujoco, model, data = self.mujoco, self.model, self.data
        tolerance = self.robot_model.contact_tolerance_m
        surfaces = (self.foam_geom, self.floor_geom, self.ledge_geom)
        return sum(min(mujoco.mj_geomDistance(model, data, geom, surface, 10.0, None)
                       for geom in geoms for surface in surfaces) <= tolerance
                   for geoms in self.wheel_geoms.values() if geoms)

class _MujocoPlate:
    """The push plate's drive (the PyBullet twin's ``PushPlate`` interface): a velocity servo on its slide joint,
    ``b (v_target - v)`` with MuJoCo's joint damping ``b`` (integrated implicitly by the Euler integrator, so
    stable at any gain) and the force ``b v_target``; ``b`` is lowered so that the force stays within
    ``max_force_n`` (module docstring). Under RK4 (a compliant profile mount) damping is explicit: ``b`` is then
    the plate's mass / step. It keeps the twin's model, data and plate joint, never the twin (which holds its plate:
    a cycle kept every dropped twin's compiled model and data until a rare full garbage collection)."""

    #: Share of the robot's mass in the servo gain ((plate mass + share x robot mass) / step). Measured on the
    #: chassis: at 1 x or 3 x the plate rams the robot's contact and throws it off up to 13% / 20% faster than
    #: the launch speed; at 0.25 it leaves within 1%, but the ramp lags and the travel time runs up to 7% long at
    #: 1.5 m/s (test_launch_twin). The Husky (50 kg, its own wheel drag, the derived launcher) leaves the edge
    #: about 21% slow at 0.8 m/s and 7-10% fast at 1.5 m/s (PyBullet: within 3%): a known difference.
    ROBOT_SHARE = 0.25

    def __init__(self, twin: MujocoLaunchTwin, spec: PushPlateSpec, push: npt.ArrayLike, face_x_m: float) -> None:
        self.spec, self.push, self.face_x_m = spec, np.asarray(push), face_x_m
        self._model, self._data, self._dof, self._qpos = twin.model, twin.data, twin.plate_dof, twin.plate_qpos
        explicit = twin.model.opt.integrator != twin.mujoco.mjtIntegrator.mjINT_EULER
        mass_kg = spec.mass_kg + (0.0 if explicit else self.ROBOT_SHARE * twin.mass_kg)
        self._gain = mass_kg / twin.model.opt.timestep   # per MuJoCo step (a twin step's substep)
        self._target, self._limit = 0.0, spec.max_force_n
        self._start_m = float(twin.data.qpos[twin.plate_qpos])
        self.driving = False

    @property
    def at_rest(self) -> bool:
        """True once the braked plate has stopped (its servo then holds it with the damping last set)."""
        return not self.driving and abs(float(self._data.qvel[self._dof])) < 1e-6

    def force(self) -> float:
        """Set the servo's damping for the coming step and return the joint force that goes with it (N)."""
        error = abs(self._target - float(self._data.qvel[self._dof]))
        gain = self._gain if error * self._gain <= self._limit else self._limit / error
        self._model.dof_damping[self._dof] = gain
        return gain * self._target

    def drive(self, speed_mps: float, time_s: float) -> None:
        """Drive at ``speed_mps`` ramped over ``ramp_s`` from the fire (``time_s`` after it)."""
        self._target = speed_mps * min(1.0, time_s / self.spec.ramp_s)
        self.driving = True

    def reached_edge(self) -> bool:
        """True once the plate's face has reached the edge line x = 0."""
        return bool(self.face_x_m + float(self._data.qpos[self._qpos]) * self.push[0] >= 0.0)

    def travel_m(self) -> float:
        """How far the plate has moved along the push from its start (m)."""
        return float(self._data.qpos[self._qpos]) - self._start_m

    def stop(self) -> None:
        """Brake to rest (the cylinder at the end of its push): target 0 with 10 x the force, from now on."""
        self._target, self._limit, self.driving = 0.0, self.spec.max_force_n * 10, False

_cache: "collections.OrderedDict[str, MujocoLaunchTwin]" = collections.OrderedDict()

def _launch_free(settings: LaunchTwinSettings) -> LaunchTwinSettings:
    """``settings`` without what only a launch's draws and drive read (designs list, speed and angle scatter, the
    speed setting's bias): settings that differ only there share a model."""
    twin = settings.twin
    return dataclasses.replace(settings, twin=dataclasses.replace(
        twin, designs=DesignSources(), speed_sigma_fraction=0.0, angle_sigma_deg=0.0,
        launcher=dataclasses.replace(twin.launcher, speed_bias_fraction=0.0)))

def _twin_key(settings, profile):
    """What needs a model of its own: everything but :func:`_launch_free`'s fields and what
    :meth:`MujocoLaunchTwin.retarget` applies to a compiled model (a robustness draw's contact reading, foam,
    Mecanum wheel drag, base plate rolling friction, centre of mass, disturbance)."""
    settings = _launch_free(settings)
    foam = dataclasses.replace(settings.twin.foam, contact_stiffness_npm=1.0, contact_damping_nspm=0.0,
                               restitution=0.0, lateral_friction=1.0, rolling_friction=0.0)
    trial = dataclasses.replace(settings.trial, start_roll_deg=0.0, force_min_n=0.0, force_max_n=0.0,
                                torque_min_nm=0.0, torque_max_nm=0.0)
    canonical = dataclasses.replace(
        settings, twin=dataclasses.replace(settings.twin, designs=DesignSources(), foam=foam, wheel_drag_torque_nm=0.0,
                                           launcher=dataclasses.replace(settings.twin.launcher,
                                                                        ledge_rolling_friction=0.0)), trial=trial,
        physics=dataclasses.replace(settings.physics, contact_model="per_contact"),
        # the profile's mass multiplier is in the profile body (part of the key): the compiled robot never reads it
        robot=dataclasses.replace(settings.robot, com_offset_z_m=0.0, profile_mass_scale=1.0),
        urdf_robot=dataclasses.replace(settings.urdf_robot, profile_mass_scale=1.0))
    return hashlib.sha256(pickle.dumps((canonical, profile), protocol=4)).hexdigest()

def twin_for(settings: LaunchTwinSettings, profile: typing.Optional[ProfileBody]) -> MujocoLaunchTwin:
    """The :class:`MujocoLaunchTwin` of ``settings`` and ``profile`` from this process's cache.

    The model a launch runs on depends on ``settings`` alone, never on what the process launched before (a killed
    and resumed run, or another worker, launches alike): every twin is compiled with the chassis's centre of mass at
    offset 0 and the early decision off, then retargeted to ``settings`` (:meth:`MujocoLaunchTwin.retarget`,
    absolute values). With the early decision on, its barriers are built for exactly ``settings`` and the twin is
    kept for exactly those; with it off (every robustness draw of a launch,
    :func:`~rollability_ros.core.sim.robustness.perturb`), one twin per robot + profile + fixed settings serves
    every draw."""
    key = ("exact-" + hashlib.sha256(pickle.dumps((_launch_free(settings), profile), protocol=4)).hexdigest()
           if settings.trial.early_decision else _twin_key(settings, profile))
    twin = _cache.pop(key, None)
    if twin is None:
        twin = MujocoLaunchTwin(dataclasses.replace(
            settings, robot=dataclasses.replace(settings.robot, com_offset_z_m=0.0),
            trial=dataclasses.replace(settings.trial, early_decision=False)), profile)
        twin.retarget(settings)
        twin.attach_energy()
    else:
        twin.retarget(settings)
    _cache[key] = twin
    while len(_cache) > CACHE_SIZE:
        _cache.popitem(last=False)
    return twin

class MujocoLaunch(LaunchEngine):
    """``sim.engine: mujoco``: launches on the kept MuJoCo twin of the robot + profile (:func:`twin_for`)."""

    @classmethod
    def simulate(cls, condition: LaunchCondition, settings: LaunchTwinSettings, seed: int,
                 profile: typing.Optional[ProfileBody], on_phase: typing.Optional[PhaseCallback] = None,
                 on_pose: typing.Optional[PoseCallback] = None, *, drive: typing.Optional[LaunchDrive] = None,
                 until_edge: bool = False) -> LaunchResult:
        """One launch (called by :func:`~rollability_ros.core.sim.launch.twin.simulate_launch`)."""
        drive = drive or launch_drive(settings, condition.speed_mps)   # before the twin: the solve launches too
        return twin_for(settings, profile).launch(condition, seed, on_phase, on_pose, drive=drive,
                                                  until_edge=until_edge)
