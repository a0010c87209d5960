"""The simulated launch twin (paper 2.2): the chassis pushed off the launcher's ledge onto memory foam, classified.

Modules, bottom first (each imports only modules above it in this list):
    ``settings``       the twin's settings dataclasses and parameter files
    ``results``        ``LaunchResult``, the phases and the callbacks that follow a launch
    ``contract``       the engine contract ``LaunchEngine`` and what the engine-neutral loop asks of an
                       engine: ``LaunchWorld``, ``LaunchPlate``, ``LaunchDrive``
    ``placement``      the launcher sized for the robot, the robot's and the plate's start, the seeded draws
    ``decision``       the early decision on the foam
    ``loop``           ``step_launch``, the event tracker, the rig's verdict and the result
    ``drive``          the stroke cylinder's speed solve
    ``twin``           ``simulate_launch`` and ``simulate_valid_launch``: the entry
    ``pybullet_twin``  ``sim.engine: pybullet``, and ``mujoco_twin``  ``sim.engine: mujoco``: one module per
                       engine, siblings that share nothing but the modules above; the engine is picked by
                       :data:`~rollability_ros.core.sim.engines.LAUNCH_ENGINES`
The other modules call the description below "the package docstring".


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
    Bullet's default damping of every multibody (0.04 linear and angular) is zeroed on it: the rig has none to
    speak of (air drag), MuJoCo none (docs/optimization.md, "The engines' disagreement on the bare robot").
Launcher sized for the robot (:mod:`~rollability_ros.core.sim.launcher_geometry`)
    The push plate's width, height, clearance and force and the ledge's depth and width are derived from the robot's
    collision geometry wherever the config leaves them 0 (the shipped ``config/launch_twin.yaml`` does; the
    built-in chassis gets the paper rig's 0.10 x 0.05 m plate 5 mm up, 200 N, and a 0.8 m ledge): the plate's face is
    centred on the height of the robot's centre of mass. :func:`check_launcher` (run by the rig's sim backend
    before a campaign) refuses a plate that would pass beneath or beside the robot and a ledge it does not fit
    on, naming the setting; a robot that does not fit on the ledge at its start (a turned start beyond the
    derived +-60 deg) is refused with a ``ValueError`` naming ``ledge_depth_m`` / ``ledge_width_m``.
Wheels (``wheel_model``: whose wheel contact and drag the twin uses)
    ``robot`` (``auto`` on a URDF robot): the robot's own: its joint drag (``urdf_robot.joint_drag_torque_nm``)
    and the body contact of ``config/sim.yaml`` on every link, as in the disturbance trials, except each wheel's
    rolling friction: ``wheel_rolling_resistance`` (a dimensionless rolling-resistance coefficient, an unknown:
    rubber tyres on a hard floor 0.005-0.02) x that wheel's radius (its collision shapes' half width across its
    axle, ``RobotModel.wheel_radii_m``), so a rolling wheel resists with that coefficient x its load whatever its
    size (the trials' 0.01 m is a coefficient of 0.3 on a 33 mm wheel: the TurtleBot3s came to rest at the edge).
    ``mecanum`` (``auto`` on the built-in chassis): the
    paper's chassis runs on Mecanum wheels, whose rollers let a wheel slide along its axle: the twin scales the
    wheels' friction along the axle by ``wheel_side_friction_factor`` (Bullet's anisotropic friction); rolling
    on the plate, a wheel resists with ``wheel_rolling_friction`` (Bullet rolling friction, a length in metres:
    the resisting force is about ``wheel_rolling_friction / wheel_radius_m`` times the load) and its motor
    back-drives against ``wheel_drag_torque_nm``. These replace the trial chassis's values on the wheel links
    because the trials model a generic geared wheel: with the trials' rolling friction 0.01 (a resisting force
    of a third of the load on a 0.03 m wheel) and drag 0.02 N m, the chassis stops within 0.1 m and never covers
    the paper's 0.34 m run at 0.8 m/s in 0.42 s. Either way ``wheel_friction_left_factor`` /
    ``wheel_friction_right_factor`` scale the wheels' friction (rig asymmetry, see below). A key of the wheel
    model not chosen set away from its default is refused (``settings.check_wheel_keys``).
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
    then changes the gate's reading as physics says. A robot the cylinder cannot get to the set speed is refused with a
    ``ValueError`` naming the physical cause from one more launch (:func:`~.drive.why_not_launched`: it tips
    over on the launcher, the plate does not push it through the stroke, or it coasts to rest short of the edge)
    and the settings that change it. ``push_through`` (the twin before issue 40): the plate's speed ramps to the
    launch speed in ``plate.ramp_s`` with at most ``plate.max_force_n`` and holds it until the chassis's base
    origin goes over the edge (or the plate's face reaches it), then brakes: the chassis leaves the edge at the
    launch speed (``edge_speed_mps``, within 5% on the shipped chassis and on one with 40 times the drag: see
    test_launch_twin). Either way the speed gate reads ``run_length_m / travel_time_s`` as on the rig. The chassis
    starts (its lowest point ``start_clearance_m`` above the ledge) where its foremost point (largest x of its
    collision shapes; PyBullet: of its links' bounding boxes unless they overstate it by more than 1 mm, as on a
    merged URDF body on turned inertial axes, ``pybullet_twin.PLACE_TOLERANCE_M``) reaches the edge line after
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
