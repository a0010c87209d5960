"""The launch twin's entry: :func:`simulate_launch` (check, size, pick the profile and the cylinder's drive, hand
over to the engine ``sim.engine`` names, :data:`~rollability_ros.core.sim.engines.LAUNCH_ENGINES`) and
:func:`simulate_valid_launch` (retries of invalid launches), as :mod:`rollability_ros.core.sim.launch` describes."""
import dataclasses
import typing

from rollability_ros.core.profile import profile_mesh_for
from rollability_ros.core.records import LaunchCondition
from rollability_ros.core.robots import ProfileBody
from rollability_ros.core.sim.launch.drive import launch_drive
from rollability_ros.core.sim.launch.placement import attempt_seed, sized_for_robot
from rollability_ros.core.sim.launch.results import LaunchResult, PhaseCallback, PoseCallback
from rollability_ros.core.sim.launch.settings import LaunchTwinSettings
from rollability_ros.core.sim.engines import LAUNCH_ENGINES, check_engine, check_restitution
from rollability_ros.core.sim.world import PAPER_RESTITUTION


def profile_body(configuration: str, settings: LaunchTwinSettings) -> typing.Optional[ProfileBody]:
    """The :class:`ProfileBody` mounted for ``configuration`` (None = baseline); see :mod:`designs`."""
    mesh = profile_mesh_for(configuration, settings.twin.designs)
    return None if mesh is None else settings.profile_body(mesh)

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
    """Launch ``condition``'s configuration off the simulated ledge and classify it (package docstring).

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
    check_restitution(settings.physics.engine, settings.physics.restitution, PAPER_RESTITUTION)
    condition.validate()
    settings = sized_for_robot(settings)[0]
    if not use_profile:
        profile = profile_body(condition.configuration, settings)
    return LAUNCH_ENGINES.get(settings.physics.engine).simulate(condition, settings, seed, profile, on_phase, on_pose,
                                                                drive=launch_drive(settings, condition.speed_mps))
