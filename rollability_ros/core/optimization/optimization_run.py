"""One optimization run: generations driven through an injected batch evaluator, logged, checkpointed, resumable.

The same loop runs in-process (``rollability optimize`` binds :func:`evaluation.evaluate_profile`) and in the
``optimizer`` node (binds EvaluateProfile action clients). The evaluator is a callable::

    evaluate_batch(heights_list, seed) -> [(successes, trials, eval_time_s, evaluator_name), ...]

one tuple per height array (``(n_variables,)``, simulation units), every profile evaluated with the same
disturbance seed. A failed evaluation must raise, never return 0 successes: the generation is then abandoned
without a checkpoint and redone on resume.

Run directory ``<output_dir>/<run_id>/``: ``config.yaml`` (the merged parameters, a ROS 2 parameter file),
``store.sqlite`` (every candidate and generation summary), ``checkpoint.json`` (after each completed generation; its SHA-256 is recorded in the store)
and, later, the designs exported by selection.

Order within generation g: population -> store each candidate -> tell -> incumbent re-evaluation (stored as
candidate index ``popsize``) -> store the generation summary -> checkpoint. A run killed anywhere in between
resumes from the last checkpoint and redoes generation g; candidates already stored for g are reused when
their heights and seed are identical (evaluations are deterministic in heights and seed) and a stored
candidate that differs is an error. Either way the stored sequence equals that of an uninterrupted run.
"""
import concurrent.futures
import os
import time

import numpy as np
import yaml

from rollability_ros.core.optimization import checkpoint as checkpoints
from rollability_ros.core.config import ConfigError, from_mapping, load_parameters, section
from rollability_ros.core.optimization.cmaes import (
    STREAM_POPULATION,
    STREAM_REEVALUATION,
    OptimizerSettings,
    ProfileOptimizer,
    derive_seed,
    random_initial_means,
)
from rollability_ros.core.results.records import CandidateRecord, GenerationRecord
from rollability_ros.core.results.store import Store

#: File name of the merged parameters inside a run directory.
RUN_CONFIG_FILENAME = "config.yaml"
#: ``kind`` of optimization runs in the store's run table.
RUN_KIND = "optimization"
#: Parameter files every optimization config is loaded on top of (the evaluator's settings).
BASE_CONFIGS = ("sim", "robot", "evaluator")


def new_run_id(now_s=None):
    """Return a run id from the local time, ``opt-YYYYmmdd-HHMMSS``."""
    return time.strftime("opt-%Y%m%d-%H%M%S", time.localtime(time.time() if now_s is None else now_s))


def optimizer_settings(parameters):
    """Return the :class:`OptimizerSettings` of a flat parameter dict (namespace ``optimizer``)."""
    return from_mapping(OptimizerSettings, section(parameters, "optimizer"), "optimizer")


def load_run_parameters(config_paths):
    """Merge :data:`BASE_CONFIGS` and ``config_paths`` (one or a list of paths or shipped names such as
    ``"paper"``; later files win, e.g. ``["optimizer", "runs/cal/calibrated.yaml"]``)."""
    if isinstance(config_paths, (str, os.PathLike)):
        config_paths = [config_paths]
    return load_parameters(list(BASE_CONFIGS) + list(config_paths))


def resolve_run_dir(run, output_dir="runs"):
    """Return the directory of ``run``: a run directory path as given, else ``<output_dir>/<run>``."""
    if os.path.isfile(os.path.join(run, RUN_CONFIG_FILENAME)):
        return os.fspath(run)
    return os.path.join(output_dir, run)


def run_id_of(run_dir):
    """The run id of a run directory: its name."""
    return os.path.basename(os.path.normpath(os.fspath(run_dir)))


def write_run_config(path, parameters):
    """Write flat ``parameters`` as a ROS 2 parameter file (``/**: {ros__parameters: {...}}``), atomically."""
    text = yaml.safe_dump({"/**": {"ros__parameters": section(parameters, "")}}, sort_keys=True)
    checkpoints.atomic_write_bytes(path, text.encode("utf-8"))


def read_run_config(run_dir):
    """Return the flat parameters saved in ``<run_dir>/config.yaml``; ``FileNotFoundError`` if it is not a run."""
    path = os.path.join(run_dir, RUN_CONFIG_FILENAME)
    if not os.path.isfile(path):
        raise FileNotFoundError(f"{run_dir} is not an optimization run (no {RUN_CONFIG_FILENAME})")
    return load_parameters(path)


def profile_screen(parameters, evaluator_settings, screen_settings=None):
    """The ``screen_profiles`` an :class:`OptimizationRun` with these flat ``parameters`` needs: the stable-pose
    screen of profiles on the robot of ``evaluator_settings`` under ``screen_settings`` (default: namespace
    ``stable_poses`` of ``parameters``, the defaults of ``config/calibration.yaml`` where absent); None when
    ``optimizer.initial_mean_screen`` is 0."""
    if optimizer_settings(parameters).initial_mean_screen == 0:
        return None
    from rollability_ros.core.sim import stable_poses

    if screen_settings is None:
        screen_settings = from_mapping(stable_poses.ScreenSettings, section(parameters, "stable_poses"),
                                       "stable_poses")
    return stable_poses.profile_screener(evaluator_settings, screen_settings)


class OptimizationRun:
    """Drive a :class:`ProfileOptimizer` generation by generation through ``evaluate_batch``.

    Parameters
    ----------
    run_dir : str
        The run directory (created for a new run; must hold ``config.yaml`` to resume).
    parameters : dict
        Flat merged parameters (:func:`config.load_parameters`); ``optimizer.*`` configures the run. On resume
        they must equal the run's ``config.yaml`` and checkpoint, else :class:`ConfigError` lists the differences.
    grid : geometry.ProfileGrid
        Gives ``n_variables`` and the height bounds ``[height_min, height_max]``.
    evaluate_batch : callable
        See the module docstring.
    resume : bool
        Continue the run in ``run_dir`` from its last checkpoint (or from scratch if it died in generation 0).
    on_candidate : callable(CandidateRecord), optional
        Called after each newly evaluated candidate is stored.
    on_generation : callable(GenerationRecord), optional
        Called after each generation is stored and checkpointed.
    screen_profiles : callable(heights_list) -> [StableScreen, ...], optional
        The stable-pose screen of half-grid heights, used when ``optimizer.initial_mean_screen`` > 0: the run then
        starts from the random initial mean with the highest quasi-static P(upright) (ties: the lowest worst
        barrier), recorded in the store's run info. Default: :func:`profile_screen` on the robot that
        ``parameters`` describe (a caller whose parameters do not hold the robot, the node, passes its own).

    ``on_candidate`` and ``on_generation`` are also public attributes, settable after construction.
    """

    def __init__(self, run_dir, parameters, grid, evaluate_batch, resume=False, on_candidate=None,
                 on_generation=None, clock=time.monotonic, screen_profiles=None):
        self.run_dir = os.fspath(run_dir)
        self.run_id = run_id_of(self.run_dir)
        self.parameters = dict(parameters)
        self.settings = optimizer_settings(self.parameters)
        self.grid = grid
        self._evaluate_batch = evaluate_batch
        self.on_candidate = on_candidate
        self.on_generation = on_generation
        self._clock = clock
        self.checkpoint_path = os.path.join(self.run_dir, checkpoints.CHECKPOINT_FILENAME)
        self.initial_mean_screen = self._screen_initial_means(screen_profiles)
        self.optimizer = self._resume() if resume else self._start()
        self.store = Store(self.run_dir)
        described = self.store.run_info(self.run_id)  # keep what selection added on an earlier pass
        info = dict(described["info"]) if described else {}
        info.update(n_variables=grid.n_variables, popsize=self.settings.popsize, seed=self.settings.seed)
        if self.initial_mean_screen is not None:
            info["initial_mean_screen"] = self.initial_mean_screen
        self.store.set_run_info(self.run_id, RUN_KIND, info)
        self._session_start_generation = self.optimizer.generation
        self._session_start_s = clock()

    def _screen_initial_means(self, screen_profiles):
        """With ``initial_mean_screen`` > 0: screen the random initial means and return ``{"chosen": index,
        "upright_probability": [...], "worst_barrier_m": [...]}``; else None (the paper's one random mean)."""
        self._initial_mean = None
        if self.settings.initial_mean_screen == 0:
            return None
        if screen_profiles is None:
            from rollability_ros.core.sim.evaluation import settings_from_parameters

            screen_profiles = profile_screen(self.parameters, settings_from_parameters(self.parameters))
        means = random_initial_means(self.settings, self.grid.n_variables, self.grid.height_min, self.grid.height_max)
        screens = screen_profiles(list(means))
        chosen = max(range(len(means)), key=lambda i: (screens[i].upright_probability, -screens[i].worst_barrier_m))
        self._initial_mean = means[chosen]
        return {"chosen": chosen, "upright_probability": [round(s.upright_probability, 4) for s in screens],
                "worst_barrier_m": [round(s.worst_barrier_m, 5) for s in screens]}

    def initial_mean_text(self):
        """One line on where CMA-ES started, for the CLI and the node log."""
        screen = self.initial_mean_screen
        if screen is None:
            return "initial mean: one random mean (optimizer.initial_mean_screen 0)"
        chosen = screen["chosen"]
        return (f"initial mean: #{chosen} of {len(screen['upright_probability'])} random means by the stable-pose "
                f"screen (quasi-static P(upright) {screen['upright_probability'][chosen]:.3f}, worst barrier "
                f"{screen['worst_barrier_m'][chosen] * 1000:.1f} mm)")

    def _new_optimizer(self):
        return ProfileOptimizer(self.grid.n_variables, self.settings, self.grid.height_min, self.grid.height_max,
                                self._clock, self._initial_mean)

    def _start(self):
        config_path = os.path.join(self.run_dir, RUN_CONFIG_FILENAME)
        if os.path.exists(config_path):
            raise ValueError(f"run {self.run_id} already exists in {self.run_dir}; resume it or choose another run id")
        optimizer = self._new_optimizer()  # validates the settings before anything is written
        os.makedirs(self.run_dir, exist_ok=True)
        write_run_config(config_path, self.parameters)
        return optimizer

    def _resume(self):
        saved = read_run_config(self.run_dir)
        differences = checkpoints.parameter_differences(saved, self.parameters)
        if differences:
            raise ConfigError(f"cannot resume run {self.run_id}: the configuration differs from its "
                              f"{RUN_CONFIG_FILENAME} ({'; '.join(differences[:8])}"
                              f"{'; ...' if len(differences) > 8 else ''}); resume with the run's own config")
        return self._from_checkpoint()

    def _from_checkpoint(self):
        """The optimizer as of the last checkpoint (a fresh one if generation 0 never completed).

        The checkpoint must be the one this run's store recorded (its SHA-256), or the next one, written just
        before a kill could record it; a missing, damaged or foreign checkpoint, or a legacy pickle, is refused
        with the reason (ConfigError) so nothing is recomputed or stored twice.
        """
        path = self.checkpoint_path
        legacy = os.path.join(self.run_dir, checkpoints.LEGACY_CHECKPOINT_FILENAME)
        if os.path.exists(legacy) and not os.path.exists(path):
            raise ConfigError(f"cannot resume run {self.run_id}: {legacy} is a pickled checkpoint of an earlier "
                              "version; it is not loaded (a pickle can run code)")
        store = getattr(self, "store", None) or Store(self.run_dir)
        recorded = ((store.run_info(self.run_id) or {}).get("info") or {}).get("checkpoint")
        generations = {g.generation for g in store.generations(run_id=self.run_id)}
        try:
            state = checkpoints.load_checkpoint(path)
        except ValueError as exc:
            raise ConfigError(f"cannot resume run {self.run_id}: {exc}") from exc
        if state is None:
            # a kill between storing generation 0's summary and writing the first checkpoint leaves {0}
            if recorded or generations - {0}:
                raise ConfigError(
                    f"cannot resume run {self.run_id}: its checkpoint {path} is missing, but the store holds "
                    f"{len(generations)} generation(s)"
                    f"{' and a checkpoint after generation ' + str(recorded['generation']) if recorded else ''}; "
                    "refusing to redo them (restore the checkpoint file)")
            return self._new_optimizer()
        if state.get("run_id") != self.run_id:
            raise ConfigError(f"cannot resume run {self.run_id}: {path} is the checkpoint of run "
                              f"{state.get('run_id')!r}")
        digest = checkpoints.file_sha256(path)
        if recorded is None or digest != recorded.get("sha256"):
            # written, but killed before the store recorded it: accepted only as the one generation after the
            # recorded checkpoint, with that generation's summary already stored
            expected = (recorded or {}).get("generation", 0) + 1
            if state["generation"] != expected or state["generation"] - 1 not in generations:
                raise ConfigError(f"cannot resume run {self.run_id}: {path} is not the checkpoint this run's store "
                                  f"recorded (SHA-256 {digest[:12]}..., generation {state['generation']}; recorded "
                                  f"{(recorded or {}).get('sha256', 'none')[:12]}..., generation "
                                  f"{(recorded or {}).get('generation')}): replaced or foreign")
            self._record_checkpoint(store, state["generation"], digest)
        checkpoints.check_same_config(state, self.parameters, path)
        try:
            return ProfileOptimizer.from_state_dict(state["optimizer"], self.grid.n_variables, self.settings,
                                                    self.grid.height_min, self.grid.height_max, self._clock,
                                                    self._initial_mean)
        except (KeyError, TypeError, ValueError) as exc:
            raise ConfigError(f"cannot resume run {self.run_id}: {path}: {exc}") from exc

    def _record_checkpoint(self, store, generation, digest):
        """Record in the run's store which checkpoint (generation, SHA-256) is the run's current one."""
        described = store.run_info(self.run_id)
        info = dict(described["info"]) if described else {}
        info["checkpoint"] = {"file": checkpoints.CHECKPOINT_FILENAME, "generation": generation, "sha256": digest}
        store.set_run_info(self.run_id, described["kind"] if described else RUN_KIND, info)

    # --- one generation ---------------------------------------------------------------------------------------
    def step(self):
        """Evaluate, log and checkpoint one generation; return its :class:`GenerationRecord`.

        If the evaluator raises, the optimizer is rolled back to the last checkpoint before the error propagates,
        so ``step()`` can simply be called again (it re-asks the same population and reuses stored candidates).
        """
        try:
            return self._step()
        except BaseException:
            self.optimizer = self._from_checkpoint()
            raise

    def _step(self):
        optimizer, settings = self.optimizer, self.settings
        generation = optimizer.generation
        stored = {c.index: c for c in self.store.candidates(run_id=self.run_id, generation=generation)}
        population = optimizer.ask()
        seeds = [derive_seed(settings.seed, generation, STREAM_POPULATION,
                             0 if settings.common_random_numbers else index) for index in range(len(population))]
        results = self._evaluate(generation, list(range(len(population))), population, seeds, stored)
        fitness = [r.fitness for r in results]
        optimizer.tell(population, fitness, [r.trials for r in results])
        request = optimizer.reevaluation_request()
        if request is not None:
            seed = derive_seed(settings.seed, generation, STREAM_REEVALUATION)
            (again,) = self._evaluate(generation, [settings.popsize], [request], [seed], stored)
            optimizer.tell_reevaluation(again.fitness, again.trials)
        best = int(np.argmax(fitness))
        record = GenerationRecord(run_id=self.run_id, generation=generation, best_fitness=fitness[best],
                                  mean_fitness=float(np.mean(fitness)), best_so_far=optimizer.best.fitness,
                                  sigma=optimizer.sigma, best_heights=tuple(population[best].tolist()),
                                  evaluations=optimizer.evaluations, elapsed_s=optimizer.elapsed_s,
                                  stamp_s=time.time())
        self.store.add_generation(record)
        digest = checkpoints.save_checkpoint(self.checkpoint_path, self.run_id, self.parameters,
                                             optimizer.state_dict(), optimizer.best.fitness)
        self._record_checkpoint(self.store, optimizer.generation, digest)
        if self.on_generation is not None:
            self.on_generation(record)
        return record

    def _evaluate(self, generation, indices, heights_list, seeds, stored):
        """Return the :class:`CandidateRecord` of each (index, heights, seed): reused if stored, else evaluated."""
        records = {}
        pending = {}
        for index, heights, seed in zip(indices, heights_list, seeds):
            previous = stored.get(index)
            if previous is None:
                pending.setdefault(seed, []).append((index, heights))
            elif previous.seed == seed and np.array_equal(previous.heights, heights):
                records[index] = previous
            else:
                raise ValueError(f"run {self.run_id}: the store holds a different candidate {index} of generation "
                                 f"{generation} than this resumed run computes (seed {previous.seed} vs {seed}); "
                                 "the store or the code changed since the run started")
        for seed, batch in pending.items():
            results = self._evaluate_batch([heights for _, heights in batch], seed)
            if len(results) != len(batch):
                raise ValueError(f"evaluator returned {len(results)} results for {len(batch)} profiles")
            for (index, heights), (successes, trials, eval_time_s, evaluator) in zip(batch, results):
                if not 0 <= successes <= trials or trials < 1:
                    raise ValueError(f"evaluator returned {successes} successes of {trials} trials for candidate "
                                     f"{index} of generation {generation}")
                record = CandidateRecord(run_id=self.run_id, generation=generation, index=index,
                                         heights=tuple(np.asarray(heights, dtype=np.float64).tolist()),
                                         fitness=successes / trials, successes=int(successes), trials=int(trials),
                                         seed=seed, eval_time_s=float(eval_time_s), evaluator=str(evaluator),
                                         stamp_s=time.time())
                self.store.add_candidate(record)
                records[index] = record
                if self.on_candidate is not None:
                    self.on_candidate(record)
        return [records[index] for index in indices]

    # --- the loop -----------------------------------------------------------------------------------------------
    def run(self, cancel_event=None):
        """Run generations until a stop criterion is met or ``cancel_event`` (a ``threading.Event``) is set.

        Returns the :class:`OptimizerResult`; cancelling keeps the last checkpoint, so the run can be resumed.
        """
        while not self.optimizer.stop() and not (cancel_event is not None and cancel_event.is_set()):
            self.step()
        return self.optimizer.result

    def eta_s(self):
        """Estimated wall time to the generation cap (or the wall-time cap if sooner), s; NaN before a generation."""
        done = self.optimizer.generation - self._session_start_generation
        if done == 0:
            return float("nan")
        per_generation_s = (self._clock() - self._session_start_s) / done
        remaining = []
        if self.settings.max_generations:
            remaining.append(max(0, self.settings.max_generations - self.optimizer.generation) * per_generation_s)
        if self.settings.max_wall_time_s:
            remaining.append(max(0.0, self.settings.max_wall_time_s - self.optimizer.elapsed_s))
        return min(remaining) if remaining else float("nan")

    def close(self):
        """Close the store."""
        self.store.close()


class SyntheticEvaluator:
    """A cheap stand-in evaluator with a known optimum, for tests, benchmarks and dry runs of the plumbing.

    Success probability ``p(h) = peak * exp(-d**2 / (2 * width**2))`` with ``d`` the RMS distance between the
    heights and ``optimum`` (simulation units). Trial ``j`` of a seed draws ``u_j ~ U(0, 1)`` from that seed and
    succeeds when ``u_j < p(h)``: profiles evaluated with the same seed share their disturbances (common random
    numbers), exactly like the physics evaluator's seeded trials.
    """

    def __init__(self, optimum, trials, width=0.1, peak=0.9, name="synthetic"):
        self.optimum = np.asarray(optimum, dtype=np.float64)
        self.trials, self.width, self.peak, self.name = int(trials), float(width), float(peak), name

    def success_probability(self, heights):
        """The true fitness ``p(h)`` of ``heights``."""
        distance = np.sqrt(np.mean((np.asarray(heights, dtype=np.float64) - self.optimum) ** 2))
        return float(self.peak * np.exp(-0.5 * (distance / self.width) ** 2))

    def __call__(self, heights_list, seed):
        """``evaluate_batch``: one (successes, trials, eval_time_s, name) per height array."""
        draws = np.random.default_rng(seed).random(self.trials)
        return [(int(np.sum(draws < self.success_probability(h))), self.trials, 0.0, self.name) for h in heights_list]


def profile_batch_evaluator(settings, trials, executor, name="local"):
    """``evaluate_batch`` over :func:`evaluation.evaluate_profile` on ``executor`` (a LocalExecutor or RayExecutor).

    The profiles of a batch are evaluated concurrently (one thread each submitting its trial batches), so the
    workers stay busy across candidates; ``trials`` per profile, ``settings`` an ``EvaluatorSettings``.
    """
    from rollability_ros.core.sim.evaluation import evaluate_profile

    def evaluate_batch(heights_list, seed):
        threads = concurrent.futures.ThreadPoolExecutor(max_workers=max(1, len(heights_list)))
        try:
            futures = [threads.submit(evaluate_profile, heights, trials, seed, settings, executor)
                       for heights in heights_list]
            results = [future.result() for future in futures]
        finally:
            threads.shutdown(wait=False, cancel_futures=True)
        return [(r.successes, r.trials, r.eval_time_s, name) for r in results]

    return evaluate_batch
