"""One optimization run: generations driven through an injected batch evaluator, logged, checkpointed, resumable.

The same loop runs in-process (``rollability optimize`` binds :func:`evaluation.evaluate_profile`) and in the
``optimizer`` node (binds EvaluateProfile action clients). The evaluator is a callable::

    evaluate_batch(heights_list, seed) -> [(successes, trials, eval_time_s, evaluator_name), ...]

one tuple per height array (``(n_variables,)``, simulation units), every profile evaluated with the same
disturbance seed. A failed evaluation must raise, never return 0 successes: the generation is then abandoned
without a checkpoint and redone on resume.

Run directory ``<output_dir>/<run_id>/`` (:mod:`~rollability_ros.core.optimization.run_directory`): ``config.yaml``
(the merged parameters, a ROS 2 parameter file), ``store.sqlite`` (every candidate and generation summary),
``checkpoint.json`` (after each completed generation; its SHA-256 is recorded in the store) and, later, the designs
exported by selection. The in-process evaluators live in :mod:`~rollability_ros.core.optimization.batch_evaluation`.

Generations are numbered from 1 (:data:`FIRST_GENERATION`) in the store, the messages, bags, logs and reports;
the seeds of generation number n are derived from its index n - 1, as before. Runs stored before this numbering
(their run info has no ``first_generation``) keep 0 when resumed, so their stored candidates still match.

The optimizer is pluggable: :class:`OptimizationRun` drives an
:class:`~rollability_ros.core.optimization.optimizer_contract.IncumbentOptimizer` (the method contract: ``ask``,
``tell``, ``stop``, ``result``, ``best``, ``sigma``, ``state_dict``, ``reevaluation_request`` /
``tell_reevaluation`` for the incumbent's re-evaluation, ``archive_rows`` -- None without an archive -- and
``archive_summary`` for a quality-diversity archive, stored in the run info under ``archive`` after every
generation). :func:`run_generations` is the one loop (stop / pause / give-up policy) that ``rollability optimize``
and the ``optimizer`` node run; :func:`~rollability_ros.core.optimization.run_directory.run_target` is the one
resolution of which run to start or continue.

Order within generation g: population -> store each candidate -> tell -> incumbent re-evaluation (stored as
candidate index ``popsize``) -> store the generation summary -> checkpoint. A run killed anywhere in between
resumes from the last checkpoint and redoes generation g; candidates already stored for g are reused when
their heights and seed are identical (evaluations are deterministic in heights and seed) and a stored
candidate that differs is an error. Either way the stored sequence equals that of an uninterrupted run.
"""
import dataclasses
import os
import threading
import time
import typing

import numpy as np

from rollability_ros.core.optimization import checkpoint as checkpoints
from rollability_ros.core.config import (ConfigError, as_list, check_given_files, edge_parse, load_parameters,
                                         settings_from_sections)
from rollability_ros.core.optimization.optimizer_contract import (
    STREAM_POPULATION,
    STREAM_RACE,
    STREAM_REEVALUATION,
    STREAM_START,
    OPTIMIZER_METHODS,
    IncumbentOptimizer,
    OptimizerResult,
    RunSettings,
    derive_seed,
    initial_mean_candidates,
)
from rollability_ros.core.profile import PrinterSpec, ProfileGrid
from rollability_ros.core.records import CandidateRecord, GenerationRecord, RunProgress
from rollability_ros.core.optimization.run_directory import (OUTPUT_DIR_PARAMETER, RUN_CONFIG_FILENAME, RUN_KIND,
                                                            check_new_run_dir, read_run_config, run_id_of,
                                                            write_run_config)
from rollability_ros.core.sim import (SETTINGS_SECTIONS, TWIN_NAMESPACE, EvaluatorSettings, ObjectiveSettings,
                                      ScreenSettings, twin_files)
from rollability_ros.core.store import Store

#: Number of a run's first generation wherever generations are shown or stored.
FIRST_GENERATION = 1


@edge_parse
def run_settings(parameters: typing.Mapping[str, object]) -> RunSettings:
    """Parse a run's flat parameters once into :class:`RunSettings` (defaults where a namespace is absent); a bad
    value raises :class:`ConfigError` naming its parameter (``optimizer.popsize out of range: 1 is not in [2,
    100000]``)."""
    return settings_from_sections(RunSettings, parameters, optional=("printer",))


@dataclasses.dataclass(frozen=True)
class RunConfig:
    """What an :class:`OptimizationRun` is handed by its edge (CLI or node): the typed settings it reads, and the
    run's flat parameters as its record (written to config.yaml and compared on resume, never parsed below)."""

    settings: RunSettings
    parameters: typing.Mapping[str, typing.Any]


@edge_parse
def run_config(parameters: typing.Mapping[str, object]) -> RunConfig:
    """The edge's one parse of a run's flat parameters (:func:`run_settings`), kept with them as the record."""
    return RunConfig(run_settings(parameters), dict(parameters))


#: The namespaces an optimization run applies: its own (:class:`RunSettings`), the evaluation's, the selection that
#: follows it, and the launch twin's (through ``objective.twin_config``: :func:`with_given_files`).
RUN_NAMESPACES = frozenset({*(field.name for field in dataclasses.fields(RunSettings)), "selection",
                            *SETTINGS_SECTIONS.values(), TWIN_NAMESPACE})


def with_given_files(parameters: typing.Mapping[str, object], config_paths: typing.Sequence[str],
                     command: str) -> dict:
    """``parameters`` with the files a user gave ``command`` merged over them (later files win), once every
    parameter in those files is one a run applies (:data:`RUN_NAMESPACES`; else :class:`ConfigError` naming the
    file, parameter and command); the files that set launch twin parameters are appended to
    ``objective.twin_config``, so the run's twin reads them."""
    check_given_files(config_paths, RUN_NAMESPACES, command)
    merged = {**parameters, **load_parameters(list(config_paths))} if config_paths else dict(parameters)
    extra = twin_files(config_paths)
    if extra:
        twin = as_list(merged.get("objective.twin_config", ObjectiveSettings().twin_config))
        merged["objective.twin_config"] = [*twin, *(path for path in extra if path not in twin)]
    return merged


def check_method_settings(settings: RunSettings) -> None:
    """Raise ``ValueError`` naming the first unusable setting of the search method ``settings.optimizer.method``
    (its :meth:`~rollability_ros.core.optimization.optimizer_contract.IncumbentOptimizer.check_settings`), before a
    run starts."""
    OPTIMIZER_METHODS.get(settings.optimizer.method).check_settings(settings)


def make_optimizer(grid: ProfileGrid, settings: RunSettings, clock: typing.Callable[[], float],
                   initial_mean: typing.Optional[np.ndarray] = None,
                   state: typing.Optional[dict] = None) -> IncumbentOptimizer:
    """The optimizer ``settings.optimizer.method`` names (:data:`OPTIMIZER_METHODS`, the only lookup of the name),
    over ``grid``'s variables and bounds, new or restored from a checkpoint ``state``; ``initial_mean``
    ``(grid.n_variables,)`` simulation units (None: the paper's random start)."""
    return OPTIMIZER_METHODS.get(settings.optimizer.method).create(grid, settings, clock, initial_mean, state)


def profile_screen(settings: RunSettings, evaluator_settings: EvaluatorSettings,
                   screen_settings: typing.Optional[ScreenSettings] = None) -> typing.Optional[typing.Callable]:
    """The ``screen_profiles`` an :class:`OptimizationRun` with these ``settings`` needs: the stable-pose screen of
    profiles on the robot of ``evaluator_settings`` under ``screen_settings`` (default: ``settings.stable_poses``,
    the defaults of ``config/calibration.yaml`` where the parameters had none); None when
    ``optimizer.initial_mean_screen`` is 0."""
    if settings.optimizer.initial_mean_screen == 0:
        return None
    from rollability_ros.core.sim import profile_screener

    return profile_screener(evaluator_settings, screen_settings or settings.stable_poses)


def check_design_space_printable(printer: typing.Optional[PrinterSpec], grid: ProfileGrid) -> None:
    """Raise ``ValueError`` naming the printer limit when no profile of ``grid`` could be printed on ``printer``
    (skipped when None: the parameters held no printer), before a long run."""
    if printer is None:
        return
    from rollability_ros.core.profile import design_space_printability

    problems = design_space_printability(grid, printer)
    if problems:
        raise ValueError("cannot optimize: " + "; ".join(problems))


class OptimizationRun:
    """Drive a :class:`ProfileOptimizer` generation by generation through ``evaluate_batch``.

    Parameters
    ----------
    run_dir : str
        The run directory (created for a new run; must hold ``config.yaml`` to resume).
    run : RunConfig
        The run's typed settings (``run.settings.optimizer`` configures the run), parsed at the edge
        (:func:`run_config`), and its flat parameters as the record (``config.yaml``); on resume these must equal
        the run's ``config.yaml`` and checkpoint, else :class:`ConfigError` lists the differences.
    grid : geometry.ProfileGrid
        Gives ``n_variables`` and the height bounds ``[height_min, height_max]``.
    evaluate_batch : callable
        See the module docstring.
    resume : bool
        Continue the run in ``run_dir`` from its last checkpoint (or from scratch if it died in its first generation).
    on_candidate : callable(CandidateRecord), optional
        Called after each newly evaluated candidate is stored.
    on_generation : callable(GenerationRecord), optional
        Called after each generation is stored and checkpointed.
    screen_profiles : callable(heights_list) -> [StableScreen, ...], optional
        The stable-pose screen of half-grid heights, used when ``optimizer.initial_mean_screen`` > 0: the run then
        starts from the random initial mean with the highest quasi-static P(upright) (ties: the lowest worst
        barrier), recorded in the store's run info; built at the edge (:func:`profile_screen` on the run's robot),
        required then.

    optimizer_factory : callable, optional
        ``factory(n_variables, settings, lower, upper, clock, initial_mean, state=None)`` -> the
        :class:`~rollability_ros.core.optimization.optimizer_contract.IncumbentOptimizer` the run drives; default
        :func:`make_optimizer` (``optimizer.method`` in ``OPTIMIZER_METHODS``).
    evaluate_trials : callable(heights_list, seed, trials), optional
        ``evaluate_batch`` with a trial count: needed for racing (``optimizer.race_looks``), see
        :meth:`_evaluate_raced`.

    ``on_candidate`` and ``on_generation`` are also public attributes, settable after construction.
    """

    def __init__(self, run_dir, run: RunConfig, grid, evaluate_batch, resume=False, on_candidate=None,
                 on_generation=None, clock=time.monotonic, screen_profiles=None, optimizer_factory=None,
                 evaluate_trials=None):
        self.run_dir = os.fspath(run_dir)
        self.run_id = run_id_of(self.run_dir)
        self.parameters = dict(run.parameters)   # the run's record (config.yaml), compared on resume
        self.run_settings = run.settings   # parsed at the edge: what runs below reads
        self.settings = self.run_settings.optimizer
        self.grid = grid
        self._evaluate_batch = evaluate_batch
        self._evaluate_trials = evaluate_trials
        if self.settings.race_stages is not None and evaluate_trials is None:
            raise ValueError("optimizer.race_looks needs an evaluator that takes a trial count (evaluate_trials)")
        self.on_candidate = on_candidate
        self.on_generation = on_generation
        self._clock = clock
        self._optimizer_factory = optimizer_factory
        self.checkpoint_path = os.path.join(self.run_dir, checkpoints.CHECKPOINT_FILENAME)
        if not resume:  # before any simulation (the start-point screen takes tens of seconds)
            check_new_run_dir(self.run_dir)
            check_design_space_printable(self.run_settings.printer, self.grid)
        self.initial_mean_screen = self._screen_initial_means(screen_profiles, resume)
        self.optimizer = self._resume() if resume else self._start()
        self.store = Store(self.run_dir)
        described = self.store.run_info(self.run_id)  # keep what selection added on an earlier pass
        info = dict(described["info"]) if described else {}
        if "first_generation" not in info:  # a run stored before generations were numbered from 1 keeps 0
            info["first_generation"] = 0 if resume and self.store.candidates(run_id=self.run_id) else FIRST_GENERATION
        self.first_generation = int(info["first_generation"])
        info.update(n_variables=grid.n_variables, popsize=self.settings.popsize, seed=self.settings.seed)
        if self.initial_mean_screen is not None:
            info["initial_mean_screen"] = self.initial_mean_screen
        self.store.set_run_info(self.run_id, RUN_KIND, info)
        self._session_start_generation = self.optimizer.generation
        self._session_start_s = clock()
        self._trials = sum(c.trials for c in self.store.candidates(run_id=self.run_id))
        generations = self.store.generations(run_id=self.run_id)
        self._last_generation: typing.Optional[GenerationRecord] = generations[-1] if generations else None

    def _screen_initial_means(self, screen_profiles, resume=False):
        """With ``initial_mean_screen`` > 0: rank the candidate start means (:func:`initial_mean_candidates`) by
        ``initial_mean_measure`` and start from the best; return the record kept in the store's run info
        (``{"chosen": index, "names": [...], "measure": ..., and per candidate "upright_probability" and
        "worst_barrier_m" (stable_poses) or "successes" and "trials" (objective)}``); else None (the paper's one random
        mean). The objective evaluates every candidate once on the search's own measure (``evaluate_batch``,
        ``optimizer.trials`` trials on one common seed of stream ``STREAM_START``); a resumed run reads that ranking
        back from its run info instead of launching again."""
        self._initial_mean = None
        if self.settings.initial_mean_screen == 0:
            return None
        means, names = initial_mean_candidates(self.settings, self.grid)
        if self.settings.initial_mean_measure == "objective":
            screen = self._stored_start_screen(names) if resume else None
            if screen is None:
                seed = derive_seed(self.settings.seed, 0, STREAM_START)
                results = self._checked(self._evaluate_batch(list(means), seed), list(range(len(means))), "start")
                successes, trials = [int(r[0]) for r in results], [int(r[1]) for r in results]
                chosen = max(range(len(means)), key=lambda i: (successes[i] / trials[i], -i))
                screen = {"chosen": chosen, "measure": "objective", "names": names, "seed": seed,
                          "successes": successes, "trials": trials}
            self._initial_mean = means[int(screen["chosen"])]
            return screen
        if screen_profiles is None:
            raise ValueError(f"optimizer.initial_mean_screen {self.settings.initial_mean_screen} needs the stable-pose "
                             "screen of the run's robot (screen_profiles, optimization_run.profile_screen)")
        screens = screen_profiles(list(means))
        chosen = max(range(len(means)), key=lambda i: (screens[i].upright_probability, -screens[i].worst_barrier_m))
        self._initial_mean = means[chosen]
        return {"chosen": chosen, "measure": "stable_poses", "names": names,
                "upright_probability": [round(s.upright_probability, 4) for s in screens],
                "worst_barrier_m": [round(s.worst_barrier_m, 5) for s in screens]}

    def _stored_start_screen(self, names):
        """The objective's ranking of the start means a resumed run stored in its run info, or None (none stored,
        or one over other candidates)."""
        with Store(self.run_dir) as store:
            described = store.run_info(self.run_id)
        screen = ((described or {}).get("info") or {}).get("initial_mean_screen")
        if not screen or screen.get("measure") != "objective" or screen.get("names") != names:
            return None
        return screen

    def initial_mean_text(self) -> str:
        """One line on where CMA-ES started, for the CLI and the node log."""
        screen = self.initial_mean_screen
        if screen is None:
            return "initial mean: one random mean (optimizer.initial_mean_screen 0)"
        chosen = screen["chosen"]
        names = screen.get("names") or []
        count = len(names) or len(screen["upright_probability"])
        which = (f"#{chosen} of {count} random means" if all(n.startswith("random ") for n in names)
                 else f"{names[chosen]}, the best of {count} candidate means (random and simple profiles)")
        if screen.get("measure") == "objective":
            return (f"initial mean: {which} on the search's own measure ({screen['successes'][chosen]}/"
                    f"{screen['trials'][chosen]} upright)")
        return (f"initial mean: {which} by the stable-pose screen (quasi-static P(upright) "
                f"{screen['upright_probability'][chosen]:.3f}, worst barrier "
                f"{screen['worst_barrier_m'][chosen] * 1000:.1f} mm)")

    def _new_optimizer(self, state=None):
        if self._optimizer_factory is None:
            return make_optimizer(self.grid, self.run_settings, self._clock, self._initial_mean, state)
        return self._optimizer_factory(self.grid.n_variables, self.settings, self.grid.height_min,
                                       self.grid.height_max, self._clock, self._initial_mean, state=state)

    def generation_number(self, index: int) -> int:
        """The number shown and stored for the generation of 0-based ``index`` (the seeds' index)."""
        return index + self.first_generation

    def start_text(self, resume: bool) -> str:
        """One line on the run starting or resuming, for the CLI and the node log."""
        completed = self.optimizer.generation
        where = (f"resuming after generation {self.generation_number(completed - 1)}" if resume and completed
                 else f"starting at generation {self.generation_number(completed)}")
        return (f"run {self.run_id} in {self.run_dir}: {where}, popsize {self.settings.popsize}, "
                f"{self.settings.trials} trials per candidate")

    def end_text(self, end: "RunEnd") -> str:
        """One line on how the run ended and its best design, for the CLI and the node log."""
        result = end.result
        best = result.best
        why = "stop service" if end.status == "stopped" else ", ".join(result.stop) or "no criterion"
        summary = (f"best fitness {best.fitness:.3f} over {best.trials} trials (first seen in generation "
                   f"{self.generation_number(best.generation)})" if best is not None else "no generation completed")
        return (f"run {self.run_id} ended after {result.generations} generation(s), {result.evaluations} "
                f"evaluations ({why}): {summary}; run directory {self.run_dir}")

    def _start(self):
        config_path = os.path.join(self.run_dir, RUN_CONFIG_FILENAME)
        check_new_run_dir(self.run_dir)
        optimizer = self._new_optimizer()  # validates the settings before anything is written
        os.makedirs(self.run_dir, exist_ok=True)
        write_run_config(config_path, self.parameters)
        return optimizer

    def _resume(self):
        saved = read_run_config(self.run_dir)
        # where the run lives is not how it computes: a run (or a study) resumed from a copied or renamed folder, or
        # named by another path to the same folder, keeps its saved output_dir and is compared on the rest
        if OUTPUT_DIR_PARAMETER in saved:
            self.parameters[OUTPUT_DIR_PARAMETER] = saved[OUTPUT_DIR_PARAMETER]
        differences = checkpoints.parameter_differences(saved, self.parameters)
        if differences:
            raise ConfigError(f"cannot resume run {self.run_id}: the configuration differs from its "
                              f"{RUN_CONFIG_FILENAME} ({'; '.join(differences[:8])}"
                              f"{'; ...' if len(differences) > 8 else ''}); resume with the run's own config")
        store = getattr(self, "store", None)
        if store is not None:
            return self._from_checkpoint(store)
        with Store(self.run_dir) as store:   # closed on a refusal too: no file of the run is left changed
            return self._from_checkpoint(store)

    def _from_checkpoint(self, store):
        """The optimizer as of the last checkpoint (a fresh one if the first generation never completed).

        The checkpoint must be the one this run's store recorded (its SHA-256), or the next one, written just
        before a kill could record it; a missing, damaged or foreign checkpoint, or a legacy pickle, is refused
        with the reason (ConfigError) so nothing is recomputed or stored twice.
        """
        path = self.checkpoint_path
        legacy = os.path.join(self.run_dir, checkpoints.LEGACY_CHECKPOINT_FILENAME)
        if os.path.exists(legacy) and not os.path.exists(path):
            raise ConfigError(f"cannot resume run {self.run_id}: {legacy} is a pickled checkpoint of an earlier "
                              "version; it is not loaded (a pickle can run code)")
        info = (store.run_info(self.run_id) or {}).get("info") or {}
        recorded = info.get("checkpoint")
        generations = {g.generation for g in store.generations(run_id=self.run_id)}
        # the stored number of the first generation (runs stored before numbering from 1 have none: 0)
        first_generation = int(info.get("first_generation", 0 if generations else FIRST_GENERATION))
        try:
            state = checkpoints.load_checkpoint(path)
        except ValueError as exc:
            raise ConfigError(f"cannot resume run {self.run_id}: {exc}") from exc
        if state is None:
            # a kill between storing the first generation's summary and writing the first checkpoint leaves it
            if recorded or generations - {first_generation}:
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
            if state["generation"] != expected or state["generation"] - 1 + first_generation not in generations:
                raise ConfigError(f"cannot resume run {self.run_id}: {path} is not the checkpoint this run's store "
                                  f"recorded (SHA-256 {digest[:12]}..., generation {state['generation']}; recorded "
                                  f"{(recorded or {}).get('sha256', 'none')[:12]}..., generation "
                                  f"{(recorded or {}).get('generation')}): replaced or foreign")
            self._record_checkpoint(store, state["generation"], digest)
        checkpoints.check_same_config(state, self.parameters, path)
        try:
            return self._new_optimizer(state["optimizer"])
        except (KeyError, TypeError, ValueError) as exc:
            raise ConfigError(f"cannot resume run {self.run_id}: {path}: {exc}") from exc

    def _record_checkpoint(self, store, generation, digest):
        """Record in the run's store which checkpoint (generation, SHA-256) is the run's current one."""
        described = store.run_info(self.run_id)
        info = dict(described["info"]) if described else {}
        info["checkpoint"] = {"file": checkpoints.CHECKPOINT_FILENAME, "generation": generation, "sha256": digest}
        store.set_run_info(self.run_id, described["kind"] if described else RUN_KIND, info)

    def _record_archive(self, optimizer):
        """Store a quality-diversity optimizer's archive (summary and every cell's elite, generations numbered as
        stored) in the run info under ``archive``; nothing for an optimizer without one."""
        rows = optimizer.archive_rows()
        if rows is None:
            return
        elites = [{**row, "generation": self.generation_number(row["generation"])} for row in rows]
        described = self.store.run_info(self.run_id)
        info = dict(described["info"]) if described else {}
        info["archive"] = {**optimizer.archive_summary(), "elites": elites}
        self.store.set_run_info(self.run_id, described["kind"] if described else RUN_KIND, info)

    # --- one generation ---------------------------------------------------------------------------------------
    def step(self) -> GenerationRecord:
        """Evaluate, log and checkpoint one generation; return its :class:`GenerationRecord`.

        If the evaluator raises, the optimizer is rolled back to the last checkpoint before the error propagates,
        so ``step()`` can simply be called again (it re-asks the same population and reuses stored candidates).
        """
        try:
            return self._step()
        except BaseException:
            self.optimizer = self._from_checkpoint(self.store)
            raise

    def _step(self):
        optimizer, settings = self.optimizer, self.settings
        index = optimizer.generation                      # the seeds' index
        generation = self.generation_number(index)        # the stored and shown number
        stored = {c.index: c for c in self.store.candidates(run_id=self.run_id, generation=generation)}
        population = optimizer.ask()
        seeds = [derive_seed(settings.seed, index, STREAM_POPULATION,
                             0 if settings.common_random_numbers else i) for i in range(len(population))]
        references = [optimizer.race_reference(heights) for heights in population] \
            if settings.race_stages is not None else [None]
        if settings.race_survivors or any(reference is not None for reference in references):
            results = self._evaluate_raced(generation, index, population, seeds[0], stored, references)
        else:
            results = self._evaluate(generation, list(range(len(population))), population, seeds, stored)
        fitness = [r.fitness for r in results]
        optimizer.tell(population, fitness, [r.trials for r in results])
        request = optimizer.reevaluation_request()
        if request is not None:
            seed = derive_seed(settings.seed, index, STREAM_REEVALUATION)
            (again,) = self._evaluate(generation, [settings.popsize], [request], [seed], stored)
            optimizer.tell_reevaluation(again.fitness, again.trials)
        best = int(np.argmax(fitness))
        record = GenerationRecord(run_id=self.run_id, generation=generation, best_fitness=fitness[best],
                                  mean_fitness=float(np.mean(fitness)), best_so_far=optimizer.best.fitness,
                                  sigma=optimizer.sigma, best_heights=tuple(population[best].tolist()),
                                  evaluations=optimizer.evaluations, elapsed_s=optimizer.elapsed_s,
                                  stamp_s=time.time())
        self.store.add_generation(record)
        self._last_generation = record
        self._record_archive(optimizer)
        digest = checkpoints.save_checkpoint(self.checkpoint_path, self.run_id, self.parameters,
                                             optimizer.state_dict(), optimizer.best.fitness)
        self._record_checkpoint(self.store, optimizer.generation, digest)
        if self.on_generation is not None:
            self.on_generation(record)
        return record

    def _evaluate(self, generation, indices, heights_list, seeds, stored):
        """Return the :class:`CandidateRecord` of each (index, heights, seed): reused if stored, else evaluated."""
        records = {}
        pending: typing.Dict[int, typing.Any] = {}
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
            results = self._checked(self._evaluate_batch([heights for _, heights in batch], seed),
                                    [index for index, _ in batch], generation)
            for (index, heights), (successes, trials, eval_time_s, evaluator) in zip(batch, results):
                records[index] = self._store_candidate(generation, index, heights, seed, successes, trials,
                                                       eval_time_s, evaluator)
        return [records[index] for index in indices]

    def _evaluate_raced(self, generation, index, population, seed, stored, references):
        """The population's :class:`CandidateRecord` s with sequential racing (``optimizer.race_looks``, module
        :mod:`~rollability_ros.core.optimization.racing`): the candidates not yet stored run in stages ending at the
        looks and then ``trials``; every stage runs all candidates still going on one common seed (stage 1 the
        generation's seed, stage k its own, stream ``STREAM_RACE``); at each look a candidate whose pooled successes
        are clearly below its bar (``references[i]``, the optimizer's :meth:`race_reference` taken before the
        generation; None: never stops) stops. A record holds the trials the candidate ran, pooled over its stages,
        under the first stage's seed. The bars come from the checkpointed state and the seeds from the run's seed,
        so a killed and resumed generation makes the same decisions. With ``optimizer.race_survivors`` (successive
        halving) at most that many of the candidates the bar left go on after each look, the best by improvement
        over their reference (:func:`racing.halving_survivors`); that decision depends on the whole population, so
        a resumed generation with some candidates stored races them all again (deterministic: the same results,
        checked against the store) and stores the rest."""
        from rollability_ros.core.optimization import racing

        settings = self.settings
        looks, stages = settings.race_looks_used, settings.race_stages
        assert stages is not None   # called only when racing
        bars = [None if r is None else racing.sequential_bar(*r) for r in references]
        records, pending = {}, []
        for number, heights in enumerate(population):
            previous = stored.get(number)
            if previous is None:
                pending.append(number)
            elif previous.seed == seed and np.array_equal(previous.heights, heights):
                records[number] = previous
            else:
                raise ValueError(f"run {self.run_id}: the store holds a different candidate {number} of generation "
                                 f"{generation} than this resumed run computes (seed {previous.seed} vs {seed})")
        halving = settings.race_survivors > 0
        racing_now = list(range(len(population))) if halving and pending else pending
        totals: typing.Dict[int, typing.List[typing.Any]] = {number: [0, 0, 0.0, ""] for number in racing_now}
        going_on = list(racing_now)
        for stage, stage_trials in enumerate(stages):
            if not going_on:
                break
            stage_seed = seed if stage == 0 else derive_seed(settings.seed, index, STREAM_RACE, stage)
            results = self._checked(self._evaluate_trials([population[i] for i in going_on], stage_seed,
                                                          stage_trials), going_on, generation)
            for number, (successes, trials, eval_time_s, evaluator) in zip(going_on, results):
                total = totals[number]
                total[0], total[1], total[2], total[3] = (total[0] + successes, total[1] + trials,
                                                          total[2] + eval_time_s, evaluator)
            if stage < len(looks):
                going_on = [i for i in going_on if not racing.sequential_stops(
                    totals[i][0], totals[i][1], bars[i], looks, settings.race_alpha)]
                if halving and going_on:
                    going_on = racing.halving_survivors({i: tuple(totals[i][:2]) for i in going_on},
                                                        {i: references[i] for i in going_on},
                                                        settings.race_survivors)
        for number, previous in records.items():
            if number in totals and (previous.successes, previous.trials) != tuple(totals[number][:2]):
                raise ValueError(f"run {self.run_id}: candidate {number} of generation {generation} raced to "
                                 f"{totals[number][0]}/{totals[number][1]} on resume, the store holds "
                                 f"{previous.successes}/{previous.trials}; the store or the code changed")
        for number in pending:
            successes, trials, eval_time_s, evaluator = totals[number]
            records[number] = self._store_candidate(generation, number, population[number], seed, successes, trials,
                                                    eval_time_s, evaluator)
        return [records[number] for number in range(len(population))]

    @staticmethod
    def _checked(results, indices, generation):
        if len(results) != len(indices):
            raise ValueError(f"evaluator returned {len(results)} results for {len(indices)} profiles")
        for number, (successes, trials, _, _) in zip(indices, results):
            if not 0 <= successes <= trials or trials < 1:
                raise ValueError(f"evaluator returned {successes} successes of {trials} trials for candidate "
                                 f"{number} of generation {generation}")
        return results

    def _store_candidate(self, generation, index, heights, seed, successes, trials, eval_time_s, evaluator):
        record = CandidateRecord(run_id=self.run_id, generation=generation, index=index,
                                 heights=tuple(np.asarray(heights, dtype=np.float64).tolist()),
                                 fitness=successes / trials, successes=int(successes), trials=int(trials),
                                 seed=seed, eval_time_s=float(eval_time_s), evaluator=str(evaluator),
                                 stamp_s=time.time())
        if self.store.add_candidate(record):
            self._trials += record.trials
        if self.on_candidate is not None:
            self.on_candidate(record)
        return record

    # --- the loop -----------------------------------------------------------------------------------------------
    def run(self, cancel_event: typing.Optional[threading.Event] = None) -> OptimizerResult:
        """Run generations until a stop criterion is met or ``cancel_event`` (a ``threading.Event``) is set.

        Returns the :class:`OptimizerResult`; cancelling keeps the last checkpoint, so the run can be resumed.
        """
        stop_requested = cancel_event.is_set if cancel_event is not None else _never
        return run_generations(self, stop_requested).result

    def eta_s(self) -> float:
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

    def progress(self) -> RunProgress:
        """Where the run stands (generations done, cap, best so far, trials evaluated), what the optimizer node
        publishes for orchestrators: they never open the run's store."""
        last = self._last_generation
        if last is None:
            return RunProgress(self.run_id, 0, self.settings.max_generations, trials=self._trials)
        return RunProgress(self.run_id, last.generation, self.settings.max_generations, last.best_so_far,
                           self._trials, last.elapsed_s)

    def close(self) -> None:
        """Close the store."""
        self.store.close()


def _never() -> bool:
    return False


@dataclasses.dataclass(frozen=True)
class RunEnd:
    """How :func:`run_generations` ended.

    ``status``: ``finished`` (a stop criterion was met), ``stopped`` (``stop_requested``), ``interrupted`` (one of
    ``interruptions`` was raised, e.g. shutdown; the checkpoint resumes it) or ``failed`` (a generation got no
    real results and ``on_evaluation_failed`` gave up; ``reason`` says why).
    """

    status: str
    result: OptimizerResult
    reason: str = ""

    @property
    def exit_code(self) -> typing.Optional[int]:
        """0 finished or stopped, 1 failed, None interrupted."""
        return {"finished": 0, "stopped": 0, "failed": 1}.get(self.status)


def give_up(error: BaseException) -> bool:
    """The default ``on_evaluation_failed``: end the run (``failed``)."""
    return False


def run_generations(run: OptimizationRun, stop_requested: typing.Callable[[], bool] = _never,
                    on_evaluation_failed: typing.Callable[[BaseException], bool] = give_up,
                    evaluation_errors: typing.Tuple[typing.Type[BaseException], ...] = (),
                    interruptions: typing.Tuple[typing.Type[BaseException], ...] = ()) -> RunEnd:
    """The optimization loop: :meth:`OptimizationRun.step` until a stop criterion or ``stop_requested()``.

    A generation whose evaluation raises one of ``evaluation_errors`` is rolled back to the checkpoint; then
    ``on_evaluation_failed(error)`` decides: True tries the generation again (a caller that paused its evaluators
    makes the next step wait for a resume), False ends the run as ``failed``. One of ``interruptions`` ends it as
    ``interrupted``. A stop request is honoured between generations, so the last one is checkpointed. Any other
    error propagates.
    """
    while not run.optimizer.stop() and not stop_requested():
        try:
            run.step()
        except interruptions:
            return RunEnd("interrupted", run.optimizer.result)
        except evaluation_errors as exc:
            if stop_requested():
                break
            if not on_evaluation_failed(exc):
                return RunEnd("failed", run.optimizer.result,
                              f"generation {run.generation_number(run.optimizer.generation)} got no real results "
                              f"({exc})")
    return RunEnd("stopped" if stop_requested() else "finished", run.optimizer.result)
