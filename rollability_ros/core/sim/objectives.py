"""What a candidate evaluation measures: the paper's disturbance trials, launches on the (calibrated) launch twin,
or a weighted mix of both (``objective`` namespace, ``config/optimizer.yaml``).

The objective lives in the evaluation, not in the optimization loop: an evaluation of ``trials`` trials with base
seed ``s`` still returns upright trials / trials, and every executor (serial, process pool, Ray, the
sim_evaluator node) runs it unchanged. What a *trial* is depends on ``objective.kind``:

``disturbance``
    the paper's trial (:mod:`rollability_ros.core.sim.trials`).
``launch_twin``
    one launch of the candidate on the launch twin (:func:`~rollability_ros.core.sim.launch.twin.simulate_valid_launch`)
    under a launch condition of a campaign configuration: the heights, speeds and angles of
    ``objective.campaign_config`` (its ``campaign`` namespace; its configurations and repetitions are not used).
    Launch ``j`` of an evaluation takes condition ``j mod C`` of the C conditions (height, then speed, then angle
    order), so ``trials`` = C x repetitions launches every condition equally often (the paper matrix: C = 20).
    The twin is that of ``objective.twin_config`` (the twin's parameter files in load order; append a
    calibrated parameter file from ``rollability calibrate`` to optimize on the calibrated twin). Both lists of
    files are read once, at the edge (:func:`resolve_launch`, through the evaluator's edge parses), into a
    :class:`ResolvedLaunch` the evaluator's settings carry to every trial job: the core reads no file. A launch
    that is still invalid after its retries counts as not upright.
``mix``
    trial ``i`` is a launch when ``floor((i + 1) w) > floor(i w)`` for ``w = objective.launch_weight``, else a
    disturbance trial: the share ``w`` of the trials are launches, spread evenly, so the fitness is the
    ``w``-weighted mean of the two success rates (exactly when ``trials w`` is a whole number).

With ``objective.robust.enabled`` every trial of any kind runs under its own draw of the uncertain quantities
(:mod:`~rollability_ros.core.sim.robustness`).

Every trial of an evaluation, of any kind and robust or not, runs on the evaluation's ``sim.engine`` through one
seam (:func:`~rollability_ros.core.sim.trials.check_engine`): disturbance trials in
:func:`~rollability_ros.core.sim.trials.make_trial_world`, launches in the twin of that engine. An engine that
cannot run a kind of trial the objective asks for is refused with a one-line error, never replaced.
Fidelities
----------
An evaluation request may name a *fidelity* (:data:`FIDELITIES`): ``screen`` (or empty) is the configured
objective above, what the optimizer's candidates are scored with; ``launch`` is what the rig measures: robust
launches on the twin under the campaign's conditions (``kind: launch_twin`` with ``robust.enabled``, the same
``campaign_config``, ``twin_config`` and robust ranges). The multi-fidelity search (docs/optimization.md) lets
cheap screen trials propose and launches decide; :func:`at_fidelity` is the one place that maps a fidelity to
an objective, so the sim_evaluator node and an in-process evaluation measure the same thing. ``world:<seed>``
(:func:`world_fidelity`) is ``launch`` with every launch in the one world drawn from ``seed``
(``robust.world_seed``): the plausible-world check (:mod:`~rollability_ros.core.sim.world_check`).

Each fidelity may run on its own engine (``objective.screen_engine``, ``objective.launch_engine``; empty = the
evaluation's ``sim.engine``): the quick default scores the optimizer's candidates on robust launches in MuJoCo (about
a sixth of a PyBullet launch's cost) and lets the race and the fresh launches decide on the PyBullet twin, the
campaign's engine. :func:`fidelity_engine` is the one place that maps a fidelity to its engine; an engine that
cannot run the fidelity's trials is refused (:func:`~rollability_ros.core.sim.trials.check_engine`), never replaced.

Trial ``i`` uses the evaluation's trial seed ``trial_seed(s, i)`` whatever its kind, so candidates evaluated with
one base seed meet the same disturbances and the same launch scatter (common random numbers).
"""
import dataclasses
import itertools
import math
import typing

from rollability_ros.core import config
from rollability_ros.core.campaign_matrix import CampaignSpec, load_campaign_spec
from rollability_ros.core.records import LaunchCondition
from rollability_ros.core.robots import ProfileBody
from rollability_ros.core.sim.launch.settings import LaunchTwinSettings, load_launch_twin_settings
from rollability_ros.core.sim.robustness import RobustSettings
from rollability_ros.core.sim.engines import check_engine, engine_names
from rollability_ros.core.sim.trial_engine import TrialOutcome

#: ``objective.kind`` values.
OBJECTIVES = ("disturbance", "launch_twin", "mix")
#: Evaluation fidelities: the configured objective (``screen``; empty means the same) and robust twin launches.
FIDELITIES = ("screen", "launch")
#: Prefix of a world fidelity, ``world:<seed>``: launch fidelity with every launch in the one world drawn from
#: ``seed`` (``objective.robust.world_seed``; the plausible-world check, :mod:`~rollability_ros.core.sim.world_check`).
WORLD_FIDELITY = "world:"
#: The configuration id the candidate's launches are filed under (the twin mounts the candidate itself).
CANDIDATE = "candidate"


@dataclasses.dataclass
class ObjectiveSettings:
    """The ``objective`` namespace: what a candidate evaluation measures (module docstring)."""

    kind: str = dataclasses.field(default="disturbance", metadata={"description": "what one trial of a candidate is: disturbance (paper 2.1.3), launch_twin (a launch on the twin under the campaign conditions) or mix"})
    launch_weight: float = dataclasses.field(default=0.5, metadata={"description": "mix only: share of each candidate's trials that are launches, fraction in (0, 1]", "range": (0.0, 1.0), "exclusive": "low"})
    campaign_config: typing.List[str] = dataclasses.field(default_factory=lambda: ["campaign"], metadata={"description": "parameter file(s) whose campaign heights x speeds x angles are the launch conditions of launch trials"})
    twin_config: typing.List[str] = dataclasses.field(default_factory=lambda: ["sim", "robot", "launch_twin"], metadata={"description": "the launch twin's parameter files in load order; append a calibrated file to optimize on the calibrated twin"})
    robust: RobustSettings = dataclasses.field(default_factory=RobustSettings)
    screen_engine: str = dataclasses.field(default="", metadata={"description": "engine of screen-fidelity evaluations (the optimizer's candidates, the selection's screen): pybullet | mujoco; empty = sim.engine"})
    launch_engine: str = dataclasses.field(default="", metadata={"description": "engine of launch-fidelity evaluations (the selection's launch race and fresh launches): pybullet | mujoco; empty = sim.engine"})

    def validate(self) -> None:
        """Raise ``ValueError`` for a rule that spans fields (each number's range is declared in its metadata and
        checked by :func:`~rollability_ros.core.config.check_settings`)."""
        for name in ("screen_engine", "launch_engine"):
            if getattr(self, name) not in ("", *engine_names()):
                raise ValueError(f"{name} must be empty (= sim.engine) or one of {', '.join(engine_names())}, "
                                 f"got {getattr(self, name)!r}")
        if self.kind not in OBJECTIVES:
            raise ValueError(f"kind must be one of {', '.join(OBJECTIVES)}, got {self.kind!r}")
        if self.kind != "disturbance" and not (self.campaign_config and all(self.campaign_config)):
            raise ValueError("campaign_config must name the campaign parameter file(s) whose launch conditions "
                             "the launch-twin objective uses")
        if self.kind != "disturbance" and not (self.twin_config and all(self.twin_config)):
            raise ValueError("twin_config must list the launch twin's parameter files")

    @property
    def launch_share(self) -> float:
        """Share of an evaluation's trials that are launches: 0, ``launch_weight`` or 1."""
        return {"disturbance": 0.0, "mix": self.launch_weight, "launch_twin": 1.0}[self.kind]


def at_fidelity(settings: "ObjectiveSettings", fidelity: str) -> "ObjectiveSettings":
    """The :class:`ObjectiveSettings` an evaluation at ``fidelity`` runs (module docstring, Fidelities): ``settings``
    itself for ``screen`` / empty, robust launches on the twin for ``launch``; ``ValueError`` for any other name."""
    if fidelity in ("", "screen"):
        return settings
    if fidelity == "launch" or fidelity.startswith(WORLD_FIDELITY):
        world = world_seed_of(fidelity)
        return dataclasses.replace(settings, kind="launch_twin", launch_weight=1.0,
                                   robust=dataclasses.replace(settings.robust, enabled=True, world_seed=world))
    raise ValueError(f"unknown evaluation fidelity {fidelity!r:.40}: use one of {', '.join(FIDELITIES)} or "
                     f"{WORLD_FIDELITY}<seed>")


def world_fidelity(world_seed: int) -> str:
    """The fidelity of launches all in the world drawn from ``world_seed`` (>= 0): ``world:<seed>``."""
    if int(world_seed) < 0:
        raise ValueError(f"a world seed is >= 0, got {world_seed}")
    return f"{WORLD_FIDELITY}{int(world_seed)}"


def world_seed_of(fidelity: str) -> int:
    """The world seed of a ``world:<seed>`` fidelity, -1 for any other (every launch draws its own world);
    ``ValueError`` naming a malformed one."""
    if not fidelity.startswith(WORLD_FIDELITY):
        return -1
    text = fidelity[len(WORLD_FIDELITY):]
    # ASCII digits only: str.isdigit also takes '²' (which int() refuses) and '٣' (which int() reads as 3); at most
    # ten of them, as int() refuses more than 4300 with a message about its own limit
    if not (text.isascii() and text.isdigit()) or len(text) > 10 or int(text) > 2 ** 32 - 1:
        raise ValueError(f"fidelity {fidelity!r:.40}: a world fidelity is {WORLD_FIDELITY}<seed>, seed in [0, 2^32 - 1]")
    return int(text)


def check_fidelity(fidelity: str) -> typing.Optional[str]:
    """Why ``fidelity`` is not an evaluation fidelity (one of :data:`FIDELITIES`, empty, or ``world:<seed>``), or
    None."""
    try:
        at_fidelity(ObjectiveSettings(), fidelity)
    except ValueError as exc:
        return str(exc)
    return None


def fidelity_engine(settings: "ObjectiveSettings", fidelity: str, default: str) -> str:
    """The engine an evaluation at ``fidelity`` runs on: ``settings.screen_engine`` (``screen`` / empty) or
    ``settings.launch_engine`` (``launch``), or ``default`` (the evaluation's ``sim.engine``) when that is empty;
    ``ValueError`` for an unknown fidelity or engine."""
    at_fidelity(settings, fidelity)   # validates the fidelity's name
    engine = settings.screen_engine if fidelity in ("", "screen") else settings.launch_engine
    if engine not in ("", *engine_names()):
        raise ValueError(f"objective.{fidelity or 'screen'}_engine must be empty (= sim.engine) or one of "
                         f"{', '.join(engine_names())}, got {engine!r}")
    return engine or default


@dataclasses.dataclass(frozen=True)
class ResolvedLaunch:
    """The launch part of an objective as its files hold it, parsed once at the edge (:func:`resolve_launch`: the
    evaluator's edge parses, the sim_evaluator node): the twin of ``objective.twin_config`` and the launch
    conditions (configuration :data:`CANDIDATE`) of ``objective.campaign_config``, with the file lists they were
    read from. Carried by the evaluator's settings to every trial job (picklable, a few kB), so the core reads no
    parameter file; an objective that names other files than these refuses it (:func:`launch_objective`) rather
    than launching a twin its files no longer describe."""

    twin_config: typing.Tuple[str, ...]
    campaign_config: typing.Tuple[str, ...]
    twin: LaunchTwinSettings
    conditions: typing.Tuple[LaunchCondition, ...]

    def names_files_of(self, settings: "ObjectiveSettings") -> bool:
        """True when ``settings`` (:class:`ObjectiveSettings`) names the files this was resolved from."""
        return (self.twin_config, self.campaign_config) == (tuple(settings.twin_config),
                                                             tuple(settings.campaign_config))


@dataclasses.dataclass(frozen=True)
class LaunchObjective:
    """The launch part of one evaluation (picklable, sent with a trial job): the launch conditions (configuration
    :data:`CANDIDATE`), the twin's settings on the evaluation's engine and the share of trials that are launches."""

    conditions: typing.Tuple[LaunchCondition, ...]
    twin: LaunchTwinSettings
    launch_share: float

    def is_launch(self, index: int) -> bool:
        """True when trial ``index`` of an evaluation is a launch (module docstring, ``mix``)."""
        return math.floor((index + 1) * self.launch_share + 1e-9) > math.floor(index * self.launch_share + 1e-9)

    def condition(self, index: int) -> LaunchCondition:
        """The launch condition of trial ``index`` (a launch): condition ``j mod C``, ``j`` = launches before it."""
        launches_before = math.floor(index * self.launch_share + 1e-9)
        return self.conditions[launches_before % len(self.conditions)]


def launch_conditions(spec: CampaignSpec) -> typing.Tuple[LaunchCondition, ...]:
    """The distinct launch conditions (height m, speed m/s, angle deg) of campaign ``spec``
    (:class:`~rollability_ros.core.campaign_matrix.CampaignSpec`), as :class:`LaunchCondition` s of configuration
    :data:`CANDIDATE`, in height, speed, angle order."""
    return tuple(LaunchCondition(CANDIDATE, float(h), float(v), float(a))
                 for h, v, a in itertools.product(spec.heights_m, spec.speeds_mps, spec.angles_deg))


@config.edge_parse
def resolve_launch(settings: "ObjectiveSettings") -> typing.Optional[ResolvedLaunch]:
    """Read the files :class:`ObjectiveSettings` ``settings`` names into a :class:`ResolvedLaunch`: the twin of
    ``twin_config`` (load order) and the conditions of ``campaign_config``'s ``campaign`` namespace. Whatever the
    objective's kind, since an evaluation at the ``launch`` fidelity launches any objective's twin; None when
    either list is empty or names an empty file (an objective without launches may name none; one with launches
    is refused by :meth:`ObjectiveSettings.validate`). A bad file raises ``ConfigError`` naming it."""
    if not (settings.twin_config and all(settings.twin_config) and settings.campaign_config
            and all(settings.campaign_config)):
        return None
    twin = load_launch_twin_settings(settings.twin_config)
    conditions = launch_conditions(load_campaign_spec(tuple(settings.campaign_config)))
    return ResolvedLaunch(tuple(settings.twin_config), tuple(settings.campaign_config), twin, conditions)


def launch_objective(settings: "ObjectiveSettings", resolved: typing.Optional[ResolvedLaunch],
                     engine: str = "pybullet", early_decision: bool = True) -> typing.Optional[LaunchObjective]:
    """The :class:`LaunchObjective` of :class:`ObjectiveSettings` ``settings`` from ``resolved``, the
    :class:`ResolvedLaunch` of its files that the edge parsed, or None for ``disturbance`` (no file is read here).

    Its launches run on ``engine``, the evaluation's ``sim.engine``, with the evaluation's
    ``trial.early_decision`` (the twin's files give the twin's physics constants, the evaluation the engine and
    the early decision of every trial it runs); an engine that cannot run launches is refused here
    (:func:`~rollability_ros.core.sim.trials.check_engine`), before any trial starts, and so is a ``resolved``
    that is missing or was read from other files than ``settings`` names (``ValueError``, one line)."""
    config.check_settings(settings, "objective")
    if settings.kind == "disturbance":
        return None
    check_engine("launch", engine)
    if resolved is None or not resolved.names_files_of(settings):
        held = ("none" if resolved is None
                else f"those of {list(resolved.twin_config)}, {list(resolved.campaign_config)}")
        raise ValueError(f"the launch twin and conditions of objective.twin_config {list(settings.twin_config)} and "
                         f"campaign_config {list(settings.campaign_config)} were not read at the edge (the settings "
                         f"hold {held}): build the evaluator's settings with its edge parse (load_settings, "
                         "settings_from_parameters, with_objective)")
    twin = dataclasses.replace(resolved.twin, physics=dataclasses.replace(resolved.twin.physics, engine=engine),
                               trial=dataclasses.replace(resolved.twin.trial, early_decision=early_decision))
    return LaunchObjective(resolved.conditions, twin, settings.launch_share)


def run_launch_trial(objective: LaunchObjective, profile: "typing.Optional[ProfileBody]",
                     index: int, seed: int) -> TrialOutcome:
    """Trial ``index`` (a launch) of an evaluation: the candidate ``profile`` (ProfileBody, None = bare chassis)
    launched on the twin under :meth:`LaunchObjective.condition` with ``seed``; a :class:`TrialOutcome`."""
    from rollability_ros.core.sim.launch.twin import simulate_valid_launch

    condition = objective.condition(index)
    result = simulate_valid_launch(condition, objective.twin, seed, profile=profile, use_profile=True)
    return TrialOutcome(index=index, seed=seed, upright=bool(result.valid and result.upright),
                        settled=bool(result.settled), steps=int(result.steps), tilt_deg=float(result.tilt_deg),
                        decided=bool(result.decided))
