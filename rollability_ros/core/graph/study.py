"""The main job: the whole design-and-validation loop through the real node graph, unattended, in simulation.

1. Bring up the graph as supervised processes (:mod:`~rollability_ros.core.graph.supervisor`): recorder (bag),
   outcome_logger (durable store), valve_controller (dry run), ``evaluators`` sim_evaluator nodes, optimizer.
2. The optimizer runs CMA-MAE or CMA-ES (``optimizer.method``) over the evaluators, selects designs A/B/C when it finishes (STL, Table 3,
   designs.yaml) and exits.
3. The rig (sim backend, the launch twin with the selected designs) and the campaign_runner join; the runner
   sends every trial of the campaign matrix to the rig and exits once the logger has stored them all.
4. The graph stops in reverse order (the recorder last, so the bag holds everything and is closed cleanly).
5. The report (figures, tables, HTML) is written from the logger's store, and the bag is read back to check it
   holds the same launch outcomes.

Everything lands in ``<output_dir>/<study id>/``: ``config/`` (copies of the parameter files the study runs
on, in load order), ``optimization/`` (run store, checkpoint, designs/ with STL files), ``outcomes.sqlite``
(the logger's store), ``bag/`` (MCAP), ``report/``, ``logs/`` (one log per node), ``node-params/`` (each node's
own overrides, its last parameter file: :func:`~rollability_ros.core.graph.bringup.override_file`), ``study.yaml``
(the parameters added for the campaign). This module never imports rclpy: it runs processes, learns the progress of the running
graph through a :class:`~rollability_ros.core.graph.progress.GraphObserver` (over ROS: the optimizer's
``optimizer_progress``, the logger's ``get_summary``; never their stores), and reads the study directory's store
for the report once the graph has stopped.

Resume (``rollability study --resume STUDY``) continues a study that was stopped or killed, on its own copied
parameter files: a bag left open by a crash is recovered first and the graph records into the next free
``bag-<n>/``; the optimization resumes from its last checkpoint, or is skipped once designs were selected; the
campaign runner skips the trials already stored. Nothing stored is redone or stored twice, and the report's
bag check reads every bag of the study.
"""
import dataclasses
import glob
import os
import shutil
import typing

import yaml

from rollability_ros.core.graph.bringup import (DEFAULT_CONFIGS, GraphSettings, NodeLaunch, add_twin_files,
                                                core_nodes, join_nodes, load_graph_settings, new_study_id,
                                                parameter_files)
from rollability_ros.core.graph.preflight import graph_namespaces
from rollability_ros.core.graph.session import SessionInfo, start_session
from rollability_ros.core.graph.progress import GraphObserver, JobProgress, ProgressDisplay, Stopwatch, eta_s
from rollability_ros.core.config import (as_list, check_given_files, check_path_component, edge_parse,
                                         integer_parameter, load_parameters)
from rollability_ros.core.records import LaunchOutcome
from rollability_ros.core.store import Store
from rollability_ros.core.graph.supervisor import Supervisor

if typing.TYPE_CHECKING:  # annotations only (the bag layer is loaded where bags are read)
    from rollability_ros.core.bags import TopicWindow

#: The optimization run inside a study directory.
OPTIMIZATION_DIR = "optimization"
#: The study's copies of its parameter files, inside the study directory.
CONFIG_DIR = "config"


#: The study's id (its campaign's run id in the outcome store), written when the study is made: a resumed study
#: keeps it whatever its folder is called now, so a copied or renamed folder continues the same campaign.
STUDY_ID_FILE = "study-id.txt"

#: Seconds between progress snapshots while a phase runs.
PROGRESS_PERIOD_S = 1.0


@dataclasses.dataclass
class StudyResult:
    """Where a study put its results, and how it ended (``ok`` False: ``reason`` says why)."""

    study_dir: str
    ok: bool
    reason: str = ""
    report_html: str = ""
    bag_dir: str = ""
    summary: str = ""


@dataclasses.dataclass(frozen=True)
class StudyConfig:
    """What a study runs on, parsed once by the command that starts it (:func:`study_config`): its parameter files
    in load order, the graph's settings, their flat parameters (the campaign's size, the optimizer's budget), its id
    and directory, and the node parameters its graph would refuse (``problems``, refused when it opens)."""

    param_files: typing.List[str]
    settings: GraphSettings
    parameters: typing.Dict[str, object]
    study_id: str
    study_dir: str
    resuming: bool = False
    problems: typing.Tuple[str, ...] = ()


@edge_parse
def study_config(extra_configs: typing.Sequence[str] = (), study_id: typing.Optional[str] = None,
                 resume: typing.Optional[str] = None) -> StudyConfig:
    """Parse a study's parameter files once: the defaults, bringup's and ``extra_configs`` (``--config``), or, to
    ``resume`` a study, its own saved copies; ``study_id`` (``--study-id``) names a new one. Raises ``ValueError``
    (:class:`~rollability_ros.core.config.ConfigError`) naming a file or parameter no node applies, a bad value of
    the graph's own, or a study directory that exists; what a node would refuse is kept in ``problems``
    (:func:`~rollability_ros.core.graph.preflight.check_graph_parameters`, the nodes' own parse, rehearsed)."""
    from rollability_ros.core.graph.preflight import check_graph_parameters

    param_files = parameter_files(["bringup", *extra_configs])
    check_given_files(extra_configs, graph_namespaces(), "rollability study")   # applied or refused, at once
    if resume is not None:
        if extra_configs or study_id:
            raise ValueError("a resumed study runs on its own saved configuration: no --config or --study-id")
        study_dir = resume_dir(resume, load_graph_settings(param_files).output_dir)
        chosen_id = recorded_study_id(study_dir)
        param_files = saved_parameter_files(study_dir)
        check_resumable(study_dir)
    settings = load_graph_settings(param_files)
    parameters = load_parameters(param_files)
    if resume is None:
        chosen_id = check_path_component(study_id, "--study-id") if study_id is not None else new_study_id()
        study_dir = os.path.join(settings.output_dir, chosen_id)
        if os.path.lexists(study_dir):
            raise ValueError(f"study directory {study_dir} already exists: continue it with --resume "
                             f"{study_dir}, or choose another --study-id")
    problems = check_graph_parameters(param_files, overrides={"rig": {"rig.twin_config": param_files}})
    return StudyConfig(param_files, settings, parameters, chosen_id, study_dir, resume is not None, tuple(problems))


class Study:
    """Runs the main job (module docstring) on ``config`` (:func:`study_config`, parsed by the command): events
    through ``say(text)``, progress snapshots (phase, generation, best, trials stored, ETA) through ``display`` (a
    :class:`~rollability_ros.core.graph.progress.ProgressDisplay`), learnt from the graph through ``observer`` (a
    :class:`~rollability_ros.core.graph.progress.GraphObserver`; None: phases only, no numbers)."""

    def __init__(self, config: StudyConfig, say: typing.Optional[typing.Callable[[str], None]] = None,
                 display: typing.Optional[ProgressDisplay] = None,
                 observer: typing.Optional[GraphObserver] = None) -> None:
        self.config = config
        self.param_files = config.param_files   # the study's copies once it saved them (make_study_dir)
        self.settings, self.parameters = config.settings, config.parameters
        self.study_id, self.study_dir, self.resuming = config.study_id, config.study_dir, config.resuming
        # display: live line on a terminal, plain lines otherwise (core/graph/progress.py); say: event lines
        self.display = display or ProgressDisplay(live=False)
        self.say = say or self.display.say
        self.observer = observer
        self._stop_requested = False
        self._shown_generation = -1
        self._campaign_clock: typing.Optional[Stopwatch] = None
        self._campaign_start_done = 0
        self.session: typing.Optional[SessionInfo] = None
        self._domain_lock: typing.Optional[typing.TextIO] = None

    def request_stop(self) -> None:
        """Ask the running study to stop at its next check (Ctrl-C handler)."""
        self._stop_requested = True

    @property
    def optimization_dir(self) -> str:
        """The study's optimization run directory (:data:`OPTIMIZATION_DIR`)."""
        return os.path.join(self.study_dir, OPTIMIZATION_DIR)

    @property
    def designs_file(self) -> str:
        """The designs.yaml the selection writes and the campaign launches (absolute)."""
        return os.path.abspath(os.path.join(self.optimization_dir, "designs", "designs.yaml"))

    @property
    def store_path(self) -> str:
        """The logger's outcome store of the study."""
        return os.path.join(self.study_dir, "outcomes.sqlite")

    @property
    def given_files(self) -> typing.List[str]:
        """The user's parameter files (``--config``; their copies once saved), after the defaults and bringup's."""
        return self.param_files[len(DEFAULT_CONFIGS) + 1:]

    def open_session(self, environ: typing.MutableMapping[str, str] = os.environ) -> SessionInfo:
        """Check the parameters, make (or reopen) the study directory, and put this process (``environ``, before
        ROS starts here: the observer and every node inherit it) on the study's own ROS domain with localhost
        discovery (:mod:`~rollability_ros.core.graph.session`); writes ``session.yaml`` and says how to join."""
        if self.session is not None:
            return self.session
        self.check_parameters()
        if self.resuming:
            self.say(f"study {self.study_id}: resuming in {self.study_dir}")
            if os.path.basename(self.study_dir) != self.study_id:
                self.say(f"  (the folder was renamed or copied: its campaign continues under its recorded id "
                         f"{self.study_id})")
        else:
            self.make_study_dir()
            self.say(f"study {self.study_id}: results in {self.study_dir}")
        self.session, self._domain_lock = start_session("study", self.study_dir, self.settings.namespace, environ,
                                                        store_path=self.store_path)
        self.say(f"study {self.study_id}: its own ROS domain {self.session.ros_domain_id} "
                 f"({self.session.discovery_range} discovery), namespace {self.session.namespace}")
        for line in self.session.join_lines():
            self.say(line)
        return self.session

    def _session_nodes(self, nodes):
        """``nodes`` as members of the study's session (its id and valve key file); its logger stores only the
        study's campaign's launch outcomes and its session's candidates and generations (the optimization)."""
        if self.session is not None:
            join_nodes(nodes, self.session.id, self.session.valve_key_file)
        for node in nodes:
            if node.module == "outcome_logger":
                node.params["session_runs"] = [self.study_id]
        return nodes

    def _optimizer(self, resume):
        optimizer = NodeLaunch("optimizer", namespace=self.settings.namespace, params={
            "run_id": OPTIMIZATION_DIR, "optimizer.output_dir": self.study_dir, "autostart": True,
            "select_designs": True, "exit_on_finish": True, "resume": resume})
        add_twin_files([optimizer], self.param_files, self.given_files)
        return optimizer

    def make_study_dir(self) -> None:
        """Make the new study's directory: its recorded id (:data:`STUDY_ID_FILE`) and its parameter files."""
        os.makedirs(self.study_dir, exist_ok=False)
        with open(os.path.join(self.study_dir, STUDY_ID_FILE), "w", encoding="utf-8") as stream:
            stream.write(self.study_id + "\n")
        self._save_parameter_files()

    def _save_parameter_files(self):
        """Copy the parameter files into ``config/`` (numbered in load order) and run on the copies."""
        folder = os.path.join(self.study_dir, CONFIG_DIR)
        os.makedirs(folder)
        copies = []
        for index, path in enumerate(self.param_files):
            copies.append(os.path.join(folder, f"{index:02d}-{os.path.basename(path)}"))
            shutil.copyfile(path, copies[-1])
        self.param_files = copies

    def bag_dirs(self) -> typing.List[str]:
        """The study's bag directories in recording order: ``bag``, then one ``bag-<n>`` per resume."""
        found = [path for path in glob.glob(os.path.join(self.study_dir, "bag*")) if os.path.isdir(path)]
        return sorted(found, key=lambda path: (len(path), path))

    def _next_bag_dir(self):
        """``bag`` for a new study; for a resumed one the next free ``bag-<n>``, after recovering open bags."""
        from rollability_ros.core.bags import is_left_open, mark_restart, recover

        existing = self.bag_dirs()
        for path in existing:
            if is_left_open(path):
                self.say(f"  recovering {path}: its recorder was killed before closing it")
                recover(path, allow_empty=True)   # an empty one too: the resumed study records into the next bag
                mark_restart(path)   # what was sent after its last kept chunk may be missing: a reported gap
        if not existing:
            return os.path.join(self.study_dir, "bag")
        return os.path.join(self.study_dir, f"bag-{len(existing) + 1}")

    @property
    def campaign_twin_config(self) -> typing.List[str]:
        """The rig's ``rig.twin_config`` in the campaign: the study's parameter files, then its ``study.yaml`` (the
        designs file the campaign launches, :meth:`_campaign_nodes`)."""
        return [*self.param_files, os.path.join(self.study_dir, "study.yaml")]

    def _campaign_nodes(self, labels):
        configurations = ["baseline", *labels]
        overrides = {"launch_twin": {"designs": {"designs_file": self.designs_file}}}
        with open(self.campaign_twin_config[-1], "w", encoding="utf-8") as stream:
            yaml.safe_dump({"/**": {"ros__parameters": overrides}}, stream)
        rig = NodeLaunch("rig", namespace=self.settings.namespace, params={"rig.backend": "sim", "rig.configurations": configurations,
                                        "rig.twin_config": self.campaign_twin_config})
        runner = NodeLaunch("campaign_runner", namespace=self.settings.namespace, restart=False, params={
            "campaign.run_id": self.study_id, "campaign.configurations": configurations,
            "runner.backend": "sim", "runner.resume": self.resuming})
        return self._session_nodes([rig, runner])

    def _progress_optimization(self):
        """Snapshots of the optimization phase: one per generation completed since the last call (a plain log
        then shows every generation), or one phase snapshot when none is new."""
        cap = integer_parameter(self.parameters, "optimizer.max_generations", 0)
        history = self.observer.optimizer_progress() if self.observer is not None else []
        if not history:
            return [JobProgress("optimizing: nodes starting", max_generations=cap)]
        run_id = history[-1].run_id
        history = [p for p in history if p.run_id == run_id]
        if not history[-1].generation:
            return [JobProgress("optimizing: first generation under evaluation", 0, history[-1].max_generations or cap)]
        new = [p for p in history if p.generation > self._shown_generation] or history[-1:]
        self._shown_generation = history[-1].generation
        return [JobProgress("optimizing", p.generation, p.max_generations or cap, p.best_so_far, p.trials,
                            eta_s=eta_s(p.generation, p.max_generations or cap, p.elapsed_s),
                            trials_label="simulated trials evaluated")
                for p in new if p.generation]

    def _progress_campaign(self, total):
        done = self.observer.stored_trials(self.study_id) if self.observer is not None else None
        if done is None:
            return [JobProgress("launch campaign: starting", trials_stored=0, trials_total=total)]
        if self._campaign_clock is None or done == 0:
            self._campaign_clock, self._campaign_start_done = Stopwatch(), done
        rate_done = done - self._campaign_start_done
        left = eta_s(rate_done, total - self._campaign_start_done, self._campaign_clock.elapsed_s)
        return [JobProgress("launch campaign (simulated rig)", trials_stored=done, trials_total=total, eta_s=left)]

    def _wait(self, supervisor, name, timeout_s, progress):
        def tick() -> None:
            try:
                for snapshot in progress():
                    self.display.update(snapshot)
            except Exception as exc:  # progress is informative only: it must not end the study
                self.display.update(f"(progress unavailable: {exc})")

        return supervisor.wait_for_exit(name, timeout_s, self.settings.poll_period_s,
                                        lambda: self._stop_requested, tick, tick_period_s=PROGRESS_PERIOD_S)

    def check_parameters(self) -> None:
        """Raise ConfigError listing every node parameter of the graph that its node would refuse, before any
        directory is made or process started (a node's own refusal would only reach its log)."""
        from rollability_ros.core.config import ConfigError

        problems = self.config.problems
        if problems:
            raise ConfigError(f"study not started: {len(problems)} invalid parameter(s):\n  " + "\n  ".join(problems))

    def run(self) -> StudyResult:
        """Run (or resume) the whole study; always stops the graph; returns a :class:`StudyResult`."""
        self.open_session()
        bag_dir = self._next_bag_dir() if self.settings.record else ""
        nodes = self._session_nodes(core_nodes(self.settings, self.study_dir, bag_dir))
        add_twin_files(nodes, self.param_files, self.given_files)   # the evaluators' twins read the user's twin keys
        supervisor = Supervisor([n.process_spec(self.param_files, self.study_dir) for n in nodes],
                                os.path.join(self.study_dir, "logs"),
                                on_event=lambda event: self.say("  " + event.text()))
        result = StudyResult(study_dir=self.study_dir, ok=False, bag_dir=bag_dir)
        campaign_started = False
        try:
            supervisor.start()
            if self._selected_labels() is None:
                resume = os.path.isfile(os.path.join(self.optimization_dir, "config.yaml"))
                self.say("resuming the optimization from its last checkpoint" if resume else
                         "optimizing the profile (the optimizer over the evaluators)")
                optimizer = self._session_nodes([self._optimizer(resume)])[0]
                supervisor.add(optimizer.process_spec(self.param_files, self.study_dir))
                code, reason = self._wait(supervisor, "optimizer", self.settings.optimization_timeout_s,
                                          self._progress_optimization)
                if code != 0:
                    result.reason = reason
                    return result
            else:
                self.say("the optimization and design selection finished before: continuing with the campaign")
            labels = self._selected_labels()
            if labels is None:
                result.reason = (f"the optimizer finished without writing the selection's designs.yaml under "
                                 f"{self.optimization_dir} (see logs/optimizer.log)")
                return result
            self.say(f"designs selected: {', '.join(labels) or 'none'}; launching the campaign on the simulated rig")
            rig, runner = self._campaign_nodes(labels)
            campaign_started = True
            supervisor.add(rig.process_spec(self.param_files, self.study_dir))
            self._wait_for_recorder(supervisor, "launch_outcomes")
            supervisor.add(runner.process_spec(self.param_files, self.study_dir))
            total = self._campaign_size(1 + len(labels))
            code, reason = self._wait(supervisor, "campaign_runner", self.settings.campaign_timeout_s,
                                      lambda: self._progress_campaign(total))
            if code != 0:
                result.reason = reason
                return result
            result.ok = True
        finally:
            self.say("stopping the node graph")
            supervisor.stop()
            if campaign_started:   # a stopped campaign too: its stored launches can be re-simulated
                self._record_campaign_designs()
        return self._report(result)

    def _wait_for_recorder(self, supervisor, topic):
        """Start a phase only once the recorder records ``topic`` of the node just started: a short campaign can
        otherwise end, and its node stop, before the recorder has subscribed (the bag would miss its records)."""
        if not self.settings.record:
            return
        full_name = f"{self.settings.namespace.rstrip('/')}/{topic}"
        if not supervisor.wait_for_output("recorder", f"recording {full_name} ", timeout_s=60):
            self.say(f"  warning: the recorder has not subscribed to {full_name}; the bag may miss its messages")

    def _selected_labels(self):
        """The labels of the selected designs (may be empty), or None before selection has written designs.yaml."""
        if not os.path.isfile(self.designs_file):
            return None
        from rollability_ros.core.profile import designs_file_labels

        return designs_file_labels(self.designs_file)   # through the designs file's one reader

    def _campaign_size(self, configurations):
        per_configuration = 1
        for key in ("campaign.heights_m", "campaign.speeds_mps", "campaign.angles_deg"):
            per_configuration *= len(as_list(self.parameters.get(key, [None])))
        return configurations * per_configuration * integer_parameter(self.parameters, "campaign.repetitions", 1)

    def _record_campaign_designs(self):
        """Record in the store the designs the campaign launched (the rig's designs_file, :meth:`_campaign_nodes`),
        so a report lists that set and not one a later ``select`` wrote beside it, and the rig's twin files, which
        ``campaign --resimulate`` loads; the logger has stopped, so the store has one writer."""
        from rollability_ros.core.campaign import record_campaign_run

        if os.path.isfile(self.store_path) and os.path.isfile(self.designs_file):
            with Store(self.store_path) as store:
                if store.trial_ids(self.study_id):
                    record_campaign_run(store, self.study_id, "sim", {"designs_file": self.designs_file,
                                                                      "mesh_files": {}}, self.campaign_twin_config)

    def _report(self, result):
        from rollability_ros.core.results import build_report, load_report_data, use_geometry_csv

        data = load_report_data(self.store_path, run_id=self.study_id)
        table3 = os.path.join(self.optimization_dir, "designs", "table3.csv")
        if os.path.isfile(table3):
            use_geometry_csv(data, table3)
        problem = ""
        if result.bag_dir:
            from rollability_ros.core.bags import missed_windows, read_records_from_bag, recording_gaps

            bagged = {o.trial_id for path in self.bag_dirs() for o in read_records_from_bag(path)[0]
                      if o.run_id == self.study_id}
            gaps = [gap for path in self.bag_dirs() for gap in recording_gaps(path)]
            windows = [window for path in self.bag_dirs() for window in missed_windows(path)]
            problem, gap_note = compare_bags_with_store(bagged, data.outcomes, gaps, windows)
            if gap_note:   # in the study's files and its report, not only on the console
                self.say(gap_note)
                with open(os.path.join(self.study_dir, RECORDING_GAPS_FILE), "w", encoding="utf-8") as stream:
                    stream.write(gap_note + "\n")
                data.notes.append(f"recording gaps ({RECORDING_GAPS_FILE}): {gap_note}")
        built = build_report(data, os.path.join(self.study_dir, "report"))
        result.report_html = built.html_path
        result.summary = built.summary
        if problem:
            result.ok = False
            result.reason = problem
        return result


#: The study's note of what its bags lost to recorder restarts, in the study directory (also in the report).
RECORDING_GAPS_FILE = "recording-gaps.txt"


#: Slack at the start of a recording gap, s: an outcome stamped just before the last message the killed recorder
#: kept may still have reached it after that message (delivery latency).
GAP_MARGIN_S = 2.0


def _format_ns(time_ns):
    import datetime

    if time_ns is None:
        return "the end of the recording"
    return datetime.datetime.fromtimestamp(time_ns / 1e9, datetime.timezone.utc).strftime("%Y-%m-%d %H:%M:%S.%f")[
        :-3] + " UTC"


def _clock_ns(time_ns):
    import datetime

    return datetime.datetime.fromtimestamp(time_ns / 1e9, datetime.timezone.utc).strftime("%H:%M:%S.%f")[:-3]


def topic_windows_text(window: typing.Mapping[str, "TopicWindow"],
                       known: typing.Optional[typing.Mapping[str, int]] = None) -> str:
    """One restart's per-topic missed windows (:func:`~rollability_ros.core.bags.recover.missed_windows`) as text:
    ``/ns/rig/pose 10:00:01.200 to 10:00:06.800 UTC (5.6 s, about 560 messages at its 100 Hz)``, one per topic.

    A steady-rate topic's loss is estimated from its rate; an event topic's is not: ``known`` (topic -> messages
    known to have been published in its window, e.g. stored launch outcomes missing from the bag) says how many,
    "nothing published" for 0, and without it the text says the loss is unknown."""
    parts = []
    for topic, entry in window.items():
        after, until, rate = entry["after_ns"], entry["until_ns"], entry["rate_hz"]
        start = "its start" if after is None else _clock_ns(after)
        end = "the end of the recording" if until is None else _clock_ns(until) + " UTC"
        text = f"{topic} {start} to {end}"
        if after is not None and until is not None:
            seconds = (until - after) / 1e9
            if known is not None and topic in known:
                lost = (f"nothing published" if not known[topic] else
                        f"{known[topic]} message(s) published then, in the store, not in the bag")
            elif entry.get("periodic", True):
                lost = (f"about {max(0, round(seconds * rate) - 1)} messages at its {rate:.3g} Hz" if rate else "")
            else:
                lost = "an event topic: what it published then is not known"
            text += f" ({seconds:.1f} s{', ' + lost if lost else ''})"
        parts.append(text)
    return ", ".join(parts)


#: The topic whose lost messages the store can count: the launch outcomes (relative name).
_COUNTED_TOPIC = "launch_outcomes"


def compare_bags_with_store(bagged_trial_ids: typing.Collection[str], stored_outcomes: typing.Iterable[LaunchOutcome],
                            gaps: typing.Sequence[typing.Tuple[int, typing.Optional[int]]],
                            topic_windows: typing.Iterable[typing.Mapping[str, "TopicWindow"]] = ()
                            ) -> typing.Tuple[str, str]:
    """Check that every stored launch outcome is in a bag, or was stamped inside a reported recording gap.

    Parameters
    ----------
    bagged_trial_ids : set of str
        Trial ids of the study's outcomes found in its bags.
    stored_outcomes : list of LaunchOutcome
        The study's outcomes in the logger's store (``stamp_s``: s since the epoch).
    gaps : list of (int, int or None)
        Windows the bags may be missing (:func:`~rollability_ros.core.bags.recover.recording_gaps`), ns.
    topic_windows : list of dict, optional
        Per restart, every topic's own missed window (:func:`~rollability_ros.core.bags.recover.missed_windows`),
        named in the note after the bag's window.

    Returns
    -------
    (str, str)
        ``problem`` (empty when the bags and the store agree, gaps allowing) and ``gap_note``: one sentence naming
        each lost window, how many stored outcomes fall in it and, with ``topic_windows``, what every recorded
        topic missed (empty without gaps).
    """
    stored = {o.trial_id: o for o in stored_outcomes}
    extra = sorted(set(bagged_trial_ids) - set(stored))
    missing = [stored[t] for t in sorted(set(stored) - set(bagged_trial_ids))]
    margin_ns = int(GAP_MARGIN_S * 1e9)
    in_gap: typing.Dict[int, typing.List[LaunchOutcome]] = {index: [] for index in range(len(gaps))}
    unexplained: typing.List[LaunchOutcome] = []
    for outcome in missing:
        stamp_ns = int(round(outcome.stamp_s * 1e9))
        index = next((i for i, (after, until) in enumerate(gaps)
                      if stamp_ns >= after - margin_ns and (until is None or stamp_ns <= until)), None)
        (unexplained if index is None else in_gap[index]).append(outcome)
    note = ""
    if gaps:
        windows = "; ".join(f"{_format_ns(after)} to {_format_ns(until)} ({len(in_gap[i])} stored outcome(s) "
                            f"not in a bag)" for i, (after, until) in enumerate(gaps))
        note = f"the recorder was restarted {len(gaps)} time(s); the bag lost the window(s): {windows}"
        per_topic = [topic_windows_text(window, _stored_in_windows(window, missing, margin_ns))
                     for window in topic_windows if window]
        if per_topic:
            note += "; every topic's missed window (its last message before the kill to its first after the " \
                    "restart): " + "; ".join(per_topic)
    problem = ""
    if extra or unexplained:
        problem = (f"the bags hold {len(bagged_trial_ids)} launch outcomes of this study, the store {len(stored)}: "
                   f"{len(unexplained)} stored outcome(s) missing from the bags outside any reported gap"
                   f"{' (e.g. ' + unexplained[0].trial_id + ')' if unexplained else ''}, {len(extra)} bagged "
                   f"outcome(s) not stored")
    return problem, note


def _stored_in_windows(window, missing, margin_ns):
    """``{launch outcome topic: stored outcomes missing from the bags stamped in its window}``."""
    counts = {}
    for topic, entry in window.items():
        after, until = entry["after_ns"], entry["until_ns"]
        if topic.rsplit("/", 1)[-1] == _COUNTED_TOPIC and after is not None and until is not None:
            counts[topic] = sum(1 for outcome in missing
                                if after - margin_ns <= int(round(outcome.stamp_s * 1e9)) <= until)
    return counts


def resume_dir(study: str, output_dir: str) -> str:
    """The directory of the study to resume: ``study`` as a path, else ``<output_dir>/<study>``; ``ValueError`` if
    it holds no study (no saved ``config/``)."""
    for candidate in (study, os.path.join(output_dir, study)):
        if os.path.isdir(os.path.join(candidate, CONFIG_DIR)):
            return os.path.normpath(candidate)
    raise ValueError(f"no study to resume at {study!r} or {os.path.join(output_dir, study)!r} (a study directory "
                     f"holds {CONFIG_DIR}/ with its parameter files)")


def recorded_study_id(study_dir: str) -> str:
    """The id a study was started under: its ``study-id.txt``; for a study made before that file existed, the one
    campaign run in its outcome store, else the folder's name (a study stopped before its campaign began)."""
    path = os.path.join(study_dir, STUDY_ID_FILE)
    if os.path.isfile(path):
        with open(path, "rb") as stream:
            recorded = stream.read(4096).decode("utf-8", errors="replace").strip()
        return check_path_component(recorded, path)
    store_path = os.path.join(study_dir, "outcomes.sqlite")
    if os.path.isfile(store_path):
        with Store(store_path) as store:
            runs = sorted({o.run_id for o in store.launch_outcomes()})
        if len(runs) > 1:
            raise ValueError(f"{store_path} holds the campaigns of several runs ({', '.join(runs)}): cannot tell "
                             f"which one this study is; write its id into {path}")
        if runs:
            return runs[0]
    return os.path.basename(os.path.normpath(study_dir))


def check_resumable(study_dir: str) -> None:
    """Raise ``ValueError`` naming the file when what a resume of ``study_dir`` reads is damaged: the outcome
    store (its logger would fail three times and the study stop with its log to read), until designs were
    selected the optimization's checkpoint and store (its optimizer would fail the same way), and the metadata of
    its closed bags (the study would run its campaign and then fail to sum up). Before any process
    starts and without writing anything (a store is opened read-only), so a refused resume leaves the study as it
    was; the cause is repaired from a copy, or the study restarted."""
    from rollability_ros.core.bags import is_left_open, recording_gaps
    from rollability_ros.core.optimization import CHECKPOINT_FILENAME, load_checkpoint

    for bag in glob.glob(os.path.join(study_dir, "bag*")):   # the summary reads every earlier bag at the end
        if os.path.isdir(bag) and not is_left_open(bag):     # one left open is recovered when the resume starts
            recording_gaps(bag)                              # BagError naming a damaged metadata.yaml
    optimization = os.path.join(study_dir, OPTIMIZATION_DIR)
    stores = [os.path.join(study_dir, "outcomes.sqlite")]
    if not os.path.isfile(os.path.join(optimization, "designs", "designs.yaml")):
        load_checkpoint(os.path.join(optimization, CHECKPOINT_FILENAME))   # ValueError naming it when damaged
        stores.append(os.path.join(optimization, "store.sqlite"))
    for path in stores:
        if os.path.isfile(path):
            with Store(path) as store:
                store.check_intact()


def saved_parameter_files(study_dir: str) -> typing.List[str]:
    """The study's copied parameter files, in load order."""
    files = sorted(glob.glob(os.path.join(study_dir, CONFIG_DIR, "*.yaml")))
    if not files:
        raise ValueError(f"{study_dir}/{CONFIG_DIR}/ holds no parameter files")
    return files
