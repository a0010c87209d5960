"""Fitness of a profile = upright trials / trials, run serially, in a local process pool, or on a Ray cluster.

What a trial is (a disturbance trial, a launch on the launch twin, or a mix) is ``settings.objective``
(:mod:`rollability_ros.core.sim.objectives`); everything below holds for every kind.

Every trial ``i`` of an evaluation with base seed ``s`` uses :func:`trial_seed` ``(s, i)``: the seed does not
depend on the profile, so candidates evaluated with the same base seed meet the same start states and
disturbances (common random numbers). A trial's outcome depends only on (profile, ``i``, trial seed, settings)
(see :mod:`rollability_ros.core.sim.trials`): ``i`` picks a launch trial's kind and condition
(:class:`~rollability_ros.core.sim.objectives.LaunchObjective`), the trial seed every draw (the robust draw too,
or the one world's seed of a ``world:<seed>`` fidelity), never an earlier trial. So every executor returns the
same outcomes for the same inputs, and trials ``k`` .. ``k + n - 1`` run alone (``first_trial``: a part of an
evaluation split over evaluators) are exactly those trials of the whole evaluation.

Executors split the trials into batches of ``evaluator.batch_trials`` and yield each finished batch;
:func:`evaluate_profile` reports every trial through ``on_trial`` as batches finish and checks the cancel event
between them (every ``evaluator.poll_interval_s`` while waiting).

Batches of profiles: :func:`evaluate_jobs` evaluates many profiles in one call of a :class:`TrialBatchEngine`
(the declared seam for an engine that steps many worlds at once); :class:`ExecutorEngine` is the CPU
engines' implementation over the executors.
"""
import abc
import collections
import concurrent.futures
import dataclasses
import hashlib
import os
import pickle
import time
import typing

import numpy as np
import numpy.typing as npt

import rollability_ros

from rollability_ros.core.config import check_given_files, edge_parse, load_parameters, settings_from_sections
from rollability_ros.core.profile import Mesh, PrinterSpec, ProfileGrid, check_heights, is_baseline, profile_mesh
from rollability_ros.core.optional import require
from rollability_ros.core.robots import ChassisSpec, ProfileBody, RobotChoice, UrdfRobotSpec, footprint_grid
from rollability_ros.core.sim.objectives import LaunchObjective, ObjectiveSettings, ResolvedLaunch, at_fidelity, \
    fidelity_engine, launch_objective, resolve_launch, run_launch_trial
from rollability_ros.core.sim.robustness import robust_settings_for, scaled_profile
from rollability_ros.core.sim.world import PhysicsParams
from rollability_ros.core.stats import wilson_interval
from rollability_ros.core.sim.engines import TRIAL_ENGINES
from rollability_ros.core.sim.trial_engine import TrialOutcome, make_trial_world, run_trial
from rollability_ros.core.sim.trials import TrialSettings
from rollability_ros.core.sim._worker_pool import MAX_WORKERS, WORKER_RSS_MB, spawn_pool

#: Largest base seed (TrialResult.seed is uint64; trial seeds are kept below 2**63 for int64 stores).
MAX_SEED = 2**64 - 1


class EvaluationCancelled(Exception):
    """The cancel event was set before all trials finished; ``outcomes`` holds the trials done so far."""

    def __init__(self, outcomes):
        super().__init__(f"evaluation cancelled after {len(outcomes)} trial(s)")
        self.outcomes = outcomes


@dataclasses.dataclass
class EvaluatorOptions:
    """How an evaluation is run (``config/evaluator.yaml``, section ``evaluator``)."""

    trials: int = dataclasses.field(default=60, metadata={
        "description": "disturbance trials per evaluation when a goal asks for 0 (count; paper 60)",
        "range": (1, 10000000)})
    max_trials: int = dataclasses.field(default=10000, metadata={
        "description": "largest trial count one EvaluateProfile goal may ask for; larger requests are refused (count)",
        "range": (1, 10000000)})
    batch_trials: int = dataclasses.field(default=5, metadata={
        "description": "trials per task handed to one worker (count); larger batches mean less overhead, coarser cancel",
        "range": (1, 10000)})
    workers: int = dataclasses.field(default=0, metadata={
        "description": "worker processes for the trials (count); 0 = one per CPU core; a count whose workers (about "
                       f"{WORKER_RSS_MB} MB each) exceed the available memory is refused at start",
        "range": (0, MAX_WORKERS)})
    ray_address: str = dataclasses.field(default="", metadata={
        "description": "host:port of an existing Ray head to hand trial batches to; empty = local process pool"})
    poll_interval_s: float = dataclasses.field(default=0.05, metadata={
        "description": "time between cancel checks while waiting for workers, s", "range": (0.001, 10.0)})

    def validate(self) -> None:
        """Raise ``ValueError`` for a rule that spans fields (each number's range is declared in its metadata and
        checked by :func:`~rollability_ros.core.config.check_settings`)."""
        if not self.trials <= self.max_trials:
            raise ValueError(f"need trials <= max_trials, got trials={self.trials}, max_trials={self.max_trials}")


@dataclasses.dataclass
class EvaluatorSettings(RobotChoice):
    """Everything a trial needs (picklable): grid, printer, physics, trial protocol, robot, evaluator options,
    the objective, and the launch twin and conditions its files hold (``resolved_launch``, read at the edge:
    :func:`load_settings`, :func:`settings_from_parameters`, :func:`with_objective`; the core reads no file).

    The robot is the built-in chassis (``robot``) unless ``urdf_robot`` names a mount link; then the URDF robot is
    used and the grid's ``length_m`` / ``width_m`` are its mount footprint's (:func:`footprint_grid`).
    ``robot_model()`` and ``profile_body(mesh)`` come from
    :class:`~rollability_ros.core.robots.urdf_robot.RobotChoice`.
    """

    grid: ProfileGrid = dataclasses.field(default_factory=ProfileGrid)
    printer: PrinterSpec = dataclasses.field(default_factory=PrinterSpec)
    physics: PhysicsParams = dataclasses.field(default_factory=PhysicsParams)
    trial: TrialSettings = dataclasses.field(default_factory=TrialSettings)
    robot: ChassisSpec = dataclasses.field(default_factory=ChassisSpec)
    evaluator: EvaluatorOptions = dataclasses.field(default_factory=EvaluatorOptions)
    urdf_robot: UrdfRobotSpec = dataclasses.field(default_factory=UrdfRobotSpec)
    objective: ObjectiveSettings = dataclasses.field(default_factory=ObjectiveSettings)
    resolved_launch: typing.Optional[ResolvedLaunch] = dataclasses.field(default=None, metadata={
        "resolved_from": ("objective.twin_config", "objective.campaign_config"),
        "description": "the launch twin and launch conditions the objective's files hold, read by the edge "
                       "(objectives.resolve_launch); None = not read, and then a launch is refused"})

    def __post_init__(self):
        self.grid = footprint_grid(self.grid, self.urdf_robot)


#: settings field -> config namespace (also the ROS parameter prefix the sim_evaluator node declares); every field
#: but ``resolved_launch``, which the edge reads from the files ``objective`` names
SETTINGS_SECTIONS = {"grid": "profile", "printer": "printer", "physics": "sim", "trial": "trial",
                     "robot": "robot", "evaluator": "evaluator", "urdf_robot": "urdf_robot", "objective": "objective"}


class CancelEvent(typing.Protocol):
    """What an evaluation polls to stop early: a ``threading.Event``, or a node's view of a goal's cancel request."""

    def is_set(self) -> bool:
        """True once the evaluation should stop (pending batches are cancelled)."""


#: One batch of trials: ``[(trial index, trial seed), ...]``.
Batch = typing.Sequence[typing.Tuple[int, int]]


@edge_parse
def load_settings(config_paths: typing.Sequence[str] = ("sim", "robot", "evaluator"),
                  node_name: str = "/**") -> "EvaluatorSettings":
    """Read :class:`EvaluatorSettings` from ROS 2 parameter files (names of shipped files or paths).

    Namespaces: ``sim`` and ``trial`` (sim.yaml), ``robot``, ``profile`` and ``printer`` (robot.yaml), ``urdf_robot``
    (a robot config such as husky.yaml),
    ``evaluator`` (evaluator.yaml). Missing keys keep their defaults; unknown keys or bad values raise
    :class:`~rollability_ros.core.config.ConfigError`.
    """
    flat = load_parameters(list(config_paths), node_name)
    return settings_from_parameters(flat)


@edge_parse
def settings_from_parameters(flat: typing.Mapping[str, object]) -> "EvaluatorSettings":
    """Parse a flat ``{dotted name: value}`` dict (the CLI's merged files) once into :class:`EvaluatorSettings`,
    with the launch twin and conditions its objective's files hold (:func:`with_objective`)."""
    settings = settings_from_sections(EvaluatorSettings, flat, SETTINGS_SECTIONS)
    return with_objective(settings, settings.objective)


@edge_parse
def with_objective(settings: "EvaluatorSettings", objective: ObjectiveSettings) -> "EvaluatorSettings":
    """``settings`` with ``objective`` (:class:`~rollability_ros.core.sim.objectives.ObjectiveSettings`) and the
    launch twin and conditions of the files it names
    (:func:`~rollability_ros.core.sim.objectives.resolve_launch`; read again only when it names other files than
    ``settings.resolved_launch`` was read from). The edge's way to change an objective's files: the core refuses
    a launch whose ``resolved_launch`` another list of files was read into."""
    resolved = settings.resolved_launch
    if resolved is None or not resolved.names_files_of(objective):
        resolved = resolve_launch(objective)
    return dataclasses.replace(settings, objective=objective, resolved_launch=resolved)


def settings_at_fidelity(settings: "EvaluatorSettings", fidelity: str) -> "EvaluatorSettings":
    """``settings`` with the objective of evaluation ``fidelity`` (:func:`~rollability_ros.core.sim.objectives.at_fidelity`:
    ``screen``/empty = as configured, ``launch`` = robust twin launches) on the fidelity's engine
    (:func:`~rollability_ros.core.sim.objectives.fidelity_engine`: ``objective.screen_engine`` /
    ``objective.launch_engine``, empty = ``sim.engine``); ``ValueError`` for an unknown fidelity or engine."""
    objective = at_fidelity(settings.objective, fidelity)
    engine = fidelity_engine(settings.objective, fidelity, settings.physics.engine)
    if objective is settings.objective and engine == settings.physics.engine:
        return settings
    return dataclasses.replace(settings, objective=objective,
                               physics=dataclasses.replace(settings.physics, engine=engine))


@edge_parse
def with_given_files(settings: "EvaluatorSettings", paths: typing.Sequence[str], command: str) -> "EvaluatorSettings":
    """``settings`` (``paths`` merged in) whose launch twin also reads those of the parameter files ``paths`` a
    user gave ``command`` that set twin parameters (:func:`twin_files`), once every parameter in them is one the
    command applies (:func:`~rollability_ros.core.config.check_given_files`): the evaluation's namespaces
    (:data:`SETTINGS_SECTIONS`) and, when its objective launches the twin, ``launch_twin``. So a twin parameter in a
    given file changes the launches or is refused, never dropped. The twin is read again with them
    (:func:`with_objective`)."""
    from rollability_ros.core.sim.launch.settings import TWIN_NAMESPACE, twin_files

    launches = settings.objective.kind != "disturbance"
    check_given_files(paths, {*SETTINGS_SECTIONS.values(), *([TWIN_NAMESPACE] if launches else [])}, command)
    extra = twin_files(paths) if launches else []
    if not extra:
        return settings
    objective = dataclasses.replace(settings.objective, twin_config=[*settings.objective.twin_config, *extra])
    return with_objective(settings, objective)


def trial_seed(base_seed: int, index: int) -> int:
    """Seed of trial ``index`` of an evaluation with ``base_seed`` (int in [0, 2**63)), via numpy SeedSequence."""
    if isinstance(base_seed, bool) or not isinstance(base_seed, (int, np.integer)) or not 0 <= base_seed <= MAX_SEED:
        raise ValueError(f"seed must be an integer in [0, 2**64), got {base_seed!r}")
    if index < 0:
        raise ValueError(f"trial index must be >= 0, got {index}")
    state = np.random.SeedSequence(int(base_seed), spawn_key=(int(index),)).generate_state(1, dtype=np.uint64)
    return int(state[0]) & (2**63 - 1)


@dataclasses.dataclass(frozen=True)
class TrialJob:
    """What a worker needs to run trials of one profile: the profile body (None = baseline), the settings and,
    for a launch-twin or mixed objective, its resolved launch part (:mod:`~rollability_ros.core.sim.objectives`)."""

    profile: typing.Optional[ProfileBody]
    settings: EvaluatorSettings
    launch: typing.Optional[LaunchObjective] = None


def profile_job(heights: typing.Optional[npt.ArrayLike], settings: EvaluatorSettings) -> TrialJob:
    """Make the :class:`TrialJob` of half-grid ``heights`` ``(grid.n_variables,)`` (simulation units; None / empty /
    flat = baseline); ``ValueError`` if bad."""
    if heights is not None and np.asarray(heights).size:
        heights = check_heights(heights, settings.grid)
    if is_baseline(heights, settings.grid.flat_tolerance):
        return TrialJob(profile=None, settings=settings, launch=_launch_part(settings))
    return mesh_job(profile_mesh(heights, settings.grid), settings)


def mesh_job(mesh: typing.Optional[Mesh], settings: EvaluatorSettings) -> TrialJob:
    """Make the :class:`TrialJob` of a profile solid (trimesh, metres, profile frame); None = baseline."""
    profile = None if mesh is None else settings.profile_body(mesh)
    return TrialJob(profile=profile, settings=settings, launch=_launch_part(settings))


def _launch_part(settings):
    """The launch part of a job: launches on the evaluation's engine, with its early decision setting, of the
    evaluation's robot: when the evaluation is of a URDF robot (``urdf_robot.mount_link`` named) and the twin's files
    describe another, the twin launches the evaluation's URDF robot (the one the profiles are made for), never the
    built-in chassis with another robot's profile on it."""
    objective = launch_objective(settings.objective, settings.resolved_launch, settings.physics.engine,
                                 settings.trial.early_decision)
    if objective is None or not settings.urdf_robot.mount_link or objective.twin.urdf_robot == settings.urdf_robot:
        return objective
    return dataclasses.replace(objective, twin=dataclasses.replace(objective.twin, urdf_robot=settings.urdf_robot))


_worker_world = None  # (job key, world): the last profile's world in this process (engines whose worlds share state)
#: Worlds of engines that own them (``TrialEngine.owns_world``: MuJoCo) kept per process, by job key: a racing
#: optimizer comes back to a generation's profiles once per stage (bench/bench_engines.py racing projection)
MUJOCO_WORLD_CACHE = 16
_mujoco_worlds: "collections.OrderedDict[str, typing.Any]" = collections.OrderedDict()


def _job_key(job):
    return hashlib.sha256(pickle.dumps(job, protocol=4)).hexdigest()


def run_robust_trial(job: TrialJob, index: int, seed: int) -> TrialOutcome:
    """Trial ``index`` of trial job ``job`` under the robustness draw of its ``seed``
    (:mod:`~rollability_ros.core.sim.robustness`): a launch on the perturbed twin, or a disturbance trial in a
    world of the evaluation's engine built for the perturbed settings."""
    robust = job.settings.objective.robust
    if job.launch is not None and job.launch.is_launch(index):
        twin = robust_settings_for(job.launch.twin, seed, robust)
        return run_launch_trial(dataclasses.replace(job.launch, twin=twin),
                                scaled_profile(job.profile, job.settings, twin), index, seed)
    settings = robust_settings_for(job.settings, seed, robust)
    # run_trial builds the world of settings.physics.engine (make_trial_world): the robust trial's engine is the
    # evaluation's, as for the plain trial; the profile weighs the drawn profile_mass_scale
    return run_trial(settings.robot_model(), scaled_profile(job.profile, job.settings, settings), index, seed,
                     settings.trial, settings.physics)


def run_batch(job: TrialJob, batch: Batch) -> typing.List[TrialOutcome]:
    """Run the trials ``batch`` = [(index, seed), ...] of ``job`` in this process, in the engine the job's
    settings name (nothing else is opened: a MuJoCo evaluation never loads PyBullet).

    The process keeps the world of the last job it ran, so consecutive batches of one profile reuse it (restored
    before every trial, see :class:`~rollability_ros.core.sim.pybullet_trials.TrialWorld`); worlds of engines that own
    their state (``TrialEngine.owns_world``: MuJoCo) are kept for the last ``MUJOCO_WORLD_CACHE`` jobs.
    """
    global _worker_world
    if job.launch is not None and all(job.launch.is_launch(index) for index, _ in batch) \
            and not job.settings.objective.robust.enabled:
        return [run_launch_trial(job.launch, job.profile, index, seed) for index, seed in batch]
    if job.settings.objective.robust.enabled:
        _worker_world = None   # every robust trial builds its own world
        return [run_robust_trial(job, index, seed) for index, seed in batch]
    key = _job_key(job)
    settings = job.settings
    if settings.physics.engine in TRIAL_ENGINES and TRIAL_ENGINES.get(settings.physics.engine).owns_world:
        world = _mujoco_worlds.pop(key, None) or make_trial_world(
            settings.robot_model(), job.profile, settings.trial, settings.physics)
        _mujoco_worlds[key] = world
        while len(_mujoco_worlds) > MUJOCO_WORLD_CACHE:
            _mujoco_worlds.popitem(last=False)
    else:
        if _worker_world is None or _worker_world[0] != key:
            _worker_world = (key, make_trial_world(settings.robot_model(), job.profile, settings.trial,
                                                   settings.physics))
        world = _worker_world[1]
    if job.launch is None:
        return [world.run(index, seed) for index, seed in batch]
    # a launch builds its own world, so the trial world above is left as it was
    return [run_launch_trial(job.launch, job.profile, index, seed) if job.launch.is_launch(index)
            else world.run(index, seed) for index, seed in batch]


def _warm(hold_s=0.2):
    """Start this worker process (its imports done) so the first batch does not pay for it; return its pid. No
    engine is opened here: the first batch opens the one its job names.

    The pool starts processes on demand: holding each warm-up task for ``hold_s`` makes every process take one.
    """
    time.sleep(hold_s)
    return os.getpid()


class TrialExecutor(abc.ABC):
    """The executor contract: where the trial batches of an evaluation run. Built in: :class:`SerialExecutor`
    (this process), :class:`LocalExecutor` (a pool of worker processes), :class:`RayExecutor` (a Ray cluster);
    :func:`make_executor` picks one from the evaluator options. Callers read :attr:`workers` and
    :attr:`in_process` instead of asking which kind they hold."""

    #: Local worker processes (an evaluation of many profiles sends whole profiles when it has >= 2 per worker);
    #: None when the executor is not a local pool.
    workers: typing.Optional[int] = None
    #: True when batches run in this process, whose engines keep one world of the kind that shares state (one job
    #: at a time).
    in_process: bool = False

    @abc.abstractmethod
    def iter_batches(self, job: "TrialJob", batches: typing.Sequence[Batch],
                     should_stop: typing.Callable[[], bool]) -> typing.Iterator[typing.List[TrialOutcome]]:
        """Yield the outcome list of each batch ``[(index, seed), ...]`` of ``job`` as it finishes; stop early
        (cancelling what is pending) once ``should_stop()`` is true."""

    def close(self) -> None:
        """Release workers or connections (default: nothing to release)."""

    def warm(self) -> typing.List[int]:
        """Block until the executor's worker processes have started their physics clients; return their pids
        (default: none to wait for)."""
        return []

    def __enter__(self) -> "TrialExecutor":
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()


class SerialExecutor(TrialExecutor):
    """Runs batches one after another in the calling process (the default of :func:`evaluate_profile`)."""

    in_process = True

    def iter_batches(self, job: TrialJob, batches: typing.Sequence[Batch],
                     should_stop: typing.Callable[[], bool]) -> typing.Iterator[typing.List[TrialOutcome]]:
        """Yield the outcome list of each batch in order; stop early when ``should_stop()`` is true."""
        for batch in batches:
            if should_stop():
                return
            yield run_batch(job, batch)


def _drain(pending, wait, cancel, should_stop, poll_interval_s):
    """Yield results of ``pending`` futures as they finish; on stop (or consumer exit) cancel the rest."""
    try:
        while pending and not should_stop():
            done, pending = wait(pending, poll_interval_s)
            for future in done:
                yield future
    finally:
        for future in pending:
            cancel(future)


class LocalExecutor(TrialExecutor):
    """A pool of persistent worker processes (spawned, each keeping its own engine worlds) on this machine.

    Parameters
    ----------
    workers : int, optional
        Number of processes; None or 0 = one per core (``os.cpu_count()``).
    poll_interval_s : float
        How often a wait for results checks the stop condition (s).
    """

    def __init__(self, workers: typing.Optional[int] = None, poll_interval_s: float = 0.05) -> None:
        self.workers = workers or os.cpu_count() or 1
        if self.workers < 1:
            raise ValueError(f"workers must be >= 1, got {workers}")
        self.poll_interval_s = poll_interval_s
        self._pool = spawn_pool(self.workers)
        self._warming = [self._pool.submit(_warm) for _ in range(self.workers)]

    def warm(self) -> typing.List[int]:
        """Block until the worker processes have started; return their pids."""
        return sorted({future.result() for future in self._warming})

    def iter_batches(self, job: TrialJob, batches: typing.Sequence[Batch],
                     should_stop: typing.Callable[[], bool]) -> typing.Iterator[typing.List[TrialOutcome]]:
        """Yield outcome lists as batches finish (any order); stop early when ``should_stop()`` is true."""
        pending = {self._pool.submit(run_batch, job, batch) for batch in batches}

        def wait(futures: typing.Iterable[concurrent.futures.Future], timeout: float) -> typing.Any:
            return concurrent.futures.wait(futures, timeout=timeout, return_when=concurrent.futures.FIRST_COMPLETED)

        for future in _drain(pending, wait, lambda f: f.cancel(), should_stop, self.poll_interval_s):
            yield future.result()

    def close(self) -> None:
        """Stop the worker processes (pending batches are cancelled)."""
        self._pool.shutdown(wait=True, cancel_futures=True)


class RayExecutor(TrialExecutor):
    """Hands trial batches to an existing Ray cluster (``ray start --head`` elsewhere) by ``address``.

    The package is shipped to the cluster's workers as a ``py_modules`` runtime environment, so the workers need
    only pybullet and numpy installed. Each Ray worker process keeps its engine worlds across tasks.
    """

    def __init__(self, address: str, poll_interval_s: float = 0.05) -> None:
        if not address:
            raise ValueError("RayExecutor needs a cluster address (host:port of the Ray head)")
        ray = require("ray", feature="the Ray executor")
        self._ray = ray
        self.poll_interval_s = poll_interval_s
        self._owns_connection = not ray.is_initialized()
        if self._owns_connection:
            package_dir = os.path.dirname(os.path.abspath(rollability_ros.__file__))
            ray.init(address=address, runtime_env={"py_modules": [package_dir]}, log_to_driver=False,
                     logging_level="WARNING", configure_logging=False)
        self._remote_batch = ray.remote(run_batch)

    def iter_batches(self, job: TrialJob, batches: typing.Sequence[Batch],
                     should_stop: typing.Callable[[], bool]) -> typing.Iterator[typing.List[TrialOutcome]]:
        """Yield outcome lists as batches finish on the cluster; stop early when ``should_stop()`` is true."""
        ray = self._ray
        job_ref = ray.put(job)
        pending = [self._remote_batch.remote(job_ref, batch) for batch in batches]

        def wait(refs: typing.Iterable[typing.Any], timeout: float) -> typing.Tuple[list, list]:
            done, rest = ray.wait(list(refs), num_returns=1, timeout=timeout)
            return done, rest

        for ref in _drain(pending, wait, lambda r: ray.cancel(r, force=False), should_stop, self.poll_interval_s):
            yield ray.get(ref)

    def close(self) -> None:
        """Disconnect from the cluster if this executor connected (the cluster keeps running)."""
        if self._owns_connection and self._ray.is_initialized():
            self._ray.shutdown()


def make_executor(options: EvaluatorOptions, workers: typing.Optional[int] = None) -> TrialExecutor:
    """The :class:`TrialExecutor` ``options`` (:class:`EvaluatorOptions`) ask for: Ray if ``ray_address`` is set,
    else a local pool (the only code that chooses an executor)."""
    if options.ray_address:
        return RayExecutor(options.ray_address, options.poll_interval_s)
    return LocalExecutor(workers if workers is not None else options.workers or None, options.poll_interval_s)


class TrialBatchEngine(abc.ABC):
    """The batched evaluator seam: runs many (profile, trial) pairs in one call.

    ``run_trials(jobs, pairs)`` gets the :class:`TrialJob` of each profile of a batch and the pairs
    ``(job position, trial index, trial seed)`` to run, and returns one outcome per pair, in the pairs' order,
    each the same outcome the job's own :func:`run_batch` gives for that (index, seed). The CPU engines run
    them as they always did (:class:`ExecutorEngine`); an engine that steps many worlds at once (MuJoCo's
    ``rollout`` on threads, a GPU engine) implements this one method and plugs into :func:`evaluate_jobs` and
    ``batch_evaluation.profile_batch_evaluator(..., engine=)`` without a change to the optimizer.
    """

    #: the evaluator name stored with each candidate's result
    name = "local"

    @abc.abstractmethod
    def run_trials(self, jobs: typing.Sequence[TrialJob],
                   pairs: typing.Sequence[typing.Tuple[int, int, int]]) -> typing.List[TrialOutcome]:
        """Outcomes (:class:`~rollability_ros.core.sim.trials.TrialOutcome`) of ``pairs`` ``(position in jobs,
        trial index, trial seed)``, in their order."""


class ExecutorEngine(TrialBatchEngine):
    """The CPU engines behind :class:`TrialBatchEngine`: each job's trials go to ``executor`` (serial, local
    pool or Ray) in tasks of ``evaluator.batch_trials`` trials (the job's whole trials with ``whole``), every
    job in its own thread so the workers stay busy across profiles, as the optimizer's evaluations run (one
    thread on the serial executor, whose trials share this process's engine worlds)."""

    def __init__(self, executor: typing.Optional[TrialExecutor] = None, whole: bool = False,
                 name: str = "local") -> None:
        self.executor, self.whole, self.name = executor or SerialExecutor(), whole, name

    def run_trials(self, jobs: typing.Sequence[TrialJob],
                   pairs: typing.Sequence[typing.Tuple[int, int, int]]) -> typing.List[TrialOutcome]:
        """Outcomes of ``pairs`` ``(position in jobs, trial index, trial seed)``, in their order (see the class)."""
        by_job: typing.Dict[int, typing.List[typing.Tuple[int, int, int]]] = {}
        for position, (job, index, seed) in enumerate(pairs):
            by_job.setdefault(job, []).append((position, index, seed))

        def run_job(job: int) -> typing.List[TrialOutcome]:
            wanted = by_job[job]
            size = len(wanted) if self.whole else jobs[job].settings.evaluator.batch_trials
            batches = [[(index, seed) for _, index, seed in wanted[start:start + size]]
                       for start in range(0, len(wanted), size)]
            return [outcome for batch in self.executor.iter_batches(jobs[job], batches, lambda: False)
                    for outcome in batch]

        outcomes: typing.List[typing.Any] = [None] * len(pairs)   # every position filled below
        # an in-process executor runs in this process's one physics client: one job after another
        threads = 1 if self.executor.in_process else max(1, len(by_job))
        with concurrent.futures.ThreadPoolExecutor(max_workers=threads) as pool:
            for job, done in zip(by_job, pool.map(run_job, list(by_job))):
                by_index = {outcome.index: outcome for outcome in done}
                for position, index, _ in by_job[job]:
                    outcomes[position] = by_index[index]
        return outcomes


def evaluate_jobs(jobs: typing.Sequence[TrialJob], trials: int, seed: int,
                  engine: TrialBatchEngine) -> typing.List["EvaluationResult"]:
    """Evaluate every :class:`TrialJob` of ``jobs`` over ``trials`` trials with base ``seed`` (trial ``i`` of
    each uses :func:`trial_seed` ``(seed, i)``: common random numbers) in one call of ``engine``
    (a :class:`TrialBatchEngine`); one :class:`EvaluationResult` per job (``eval_time_s``: the whole batch's)."""
    for job in jobs:
        _check_request(trials, seed, job.settings.evaluator)
    seeds = [trial_seed(seed, index) for index in range(trials)]
    pairs = [(job, index, seeds[index]) for job in range(len(jobs)) for index in range(trials)]
    started = time.perf_counter()
    outcomes = engine.run_trials(list(jobs), pairs)
    elapsed_s = time.perf_counter() - started
    if len(outcomes) != len(pairs):
        raise ValueError(f"trial engine {engine.name} returned {len(outcomes)} outcomes for {len(pairs)} pairs")
    results = []
    for position in range(len(jobs)):
        own = sorted(outcomes[position * trials:(position + 1) * trials], key=lambda outcome: outcome.index)
        successes = sum(outcome.upright for outcome in own)
        low, high = wilson_interval(successes, trials)
        results.append(EvaluationResult(fitness=successes / trials, successes=successes, trials=trials, ci_low=low,
                                        ci_high=high, eval_time_s=elapsed_s, trial_results=own))
    return results


@dataclasses.dataclass(frozen=True)
class EvaluationResult:
    """Fitness of a profile with its Wilson 95% interval and every trial's outcome (sorted by index)."""

    fitness: float
    successes: int
    trials: int
    ci_low: float
    ci_high: float
    eval_time_s: float
    trial_results: typing.List[TrialOutcome]


def request_problem(trials: int, first_trial: int, max_trials: int) -> typing.Optional[str]:
    """Why trials ``first_trial`` .. ``first_trial + trials - 1`` of an evaluation cannot be asked for (None if they
    can): ``trials`` in [1, ``max_trials``] and the range ending within ``max_trials`` (a part of a split
    evaluation may run no trial its whole evaluation could not)."""
    if isinstance(trials, bool) or not isinstance(trials, (int, np.integer)) or not 1 <= trials <= max_trials:
        return f"trials must be an integer in [1, {max_trials}], got {trials!r}"
    if isinstance(first_trial, bool) or not isinstance(first_trial, (int, np.integer)) or first_trial < 0:
        return f"first_trial must be an integer >= 0, got {first_trial!r}"
    if first_trial + trials > max_trials:
        return (f"first_trial + trials must be at most max_trials {max_trials} (trials {first_trial}.."
                f"{first_trial + trials - 1}), got first_trial {first_trial}, trials {trials}")
    return None


def _check_request(trials, seed, options, first_trial=0):
    problem = request_problem(trials, first_trial, options.max_trials)
    if problem:
        raise ValueError(problem)
    trial_seed(seed, 0)  # validates the seed


def evaluate_job(job: TrialJob, trials: int, seed: int, executor: typing.Optional[TrialExecutor] = None,
                 on_trial: typing.Optional[typing.Callable[[TrialOutcome], None]] = None,
                 cancel_event: typing.Optional[CancelEvent] = None, first_trial: int = 0) -> EvaluationResult:
    """Run ``trials`` trials of ``job`` (a :class:`TrialJob`) with base ``seed``, from trial ``first_trial``; see
    :func:`evaluate_profile`."""
    options = job.settings.evaluator
    _check_request(trials, seed, options, first_trial)
    executor = executor or SerialExecutor()
    seeds = [(index, trial_seed(seed, index)) for index in range(first_trial, first_trial + trials)]
    batches = [seeds[start:start + options.batch_trials] for start in range(0, trials, options.batch_trials)]
    stopped = cancel_event.is_set if cancel_event is not None else (lambda: False)
    outcomes = []
    started = time.perf_counter()
    for batch_outcomes in executor.iter_batches(job, batches, stopped):
        for outcome in batch_outcomes:
            outcomes.append(outcome)
            if on_trial is not None:
                on_trial(outcome)
        if stopped():
            break
    outcomes.sort(key=lambda outcome: outcome.index)
    if len(outcomes) < trials:
        raise EvaluationCancelled(outcomes)
    successes = sum(outcome.upright for outcome in outcomes)
    low, high = wilson_interval(successes, trials)
    return EvaluationResult(fitness=successes / trials, successes=successes, trials=trials, ci_low=low, ci_high=high,
                            eval_time_s=time.perf_counter() - started, trial_results=outcomes)


def evaluate_profile(heights: typing.Optional[npt.ArrayLike], trials: int, seed: int, settings: EvaluatorSettings,
                     executor: typing.Optional[TrialExecutor] = None,
                     on_trial: typing.Optional[typing.Callable[[TrialOutcome], None]] = None,
                     cancel_event: typing.Optional[CancelEvent] = None, first_trial: int = 0) -> EvaluationResult:
    """Evaluate the profile of half-grid ``heights`` (None / empty / all zero = baseline) over ``trials`` trials.

    Parameters
    ----------
    heights : array-like of float, shape (rows*cols,), or None
        Vertex heights in simulation units (:mod:`rollability_ros.core.profile.geometry`).
    trials : int
        Number of trials, 1 .. ``settings.evaluator.max_trials``.
    seed : int
        Base seed in [0, 2**64); trial ``i`` uses ``trial_seed(seed, i)``.
    settings : EvaluatorSettings
    executor : SerialExecutor | LocalExecutor | RayExecutor, optional
        Where trials run; None = serially in this process. The caller owns (and closes) the executor.
    on_trial : callable(TrialOutcome), optional
        Called in this thread as each trial's batch completes (completion order, not index order).
    cancel_event : threading.Event-like, optional
        When set, pending batches are cancelled and :class:`EvaluationCancelled` is raised.
    first_trial : int, optional
        Run trials ``first_trial`` .. ``first_trial + trials - 1`` of the evaluation with ``seed`` (a part of a
        split evaluation, :mod:`~rollability_ros.core.optimization.evaluator_pool`); their outcomes keep those
        indices, and are those trials' outcomes in the whole evaluation. ``first_trial + trials`` is at most
        ``settings.evaluator.max_trials``.

    Returns
    -------
    EvaluationResult
        ``trials`` is the trials run; raises ``ValueError`` for bad heights, trials, first_trial or seed.
    """
    return evaluate_job(profile_job(heights, settings), trials, seed, executor, on_trial, cancel_event, first_trial)


def evaluate_mesh(mesh: typing.Optional[Mesh], trials: int, seed: int, settings: EvaluatorSettings,
                  executor: typing.Optional[TrialExecutor] = None,
                  on_trial: typing.Optional[typing.Callable[[TrialOutcome], None]] = None,
                  cancel_event: typing.Optional[CancelEvent] = None) -> EvaluationResult:
    """Evaluate a profile solid (e.g. from :func:`~rollability_ros.core.profile.geometry.load_profile_mesh`); see above."""
    return evaluate_job(mesh_job(mesh, settings), trials, seed, executor, on_trial, cancel_event)
