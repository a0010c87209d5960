"""optimizer: a CMA-ES or CMA-MAE profile optimization (``core.optimization_run``) whose candidates are evaluated
by every EvaluateProfile action server in the graph (one or many ``sim_evaluator`` nodes, ``core.evaluator_pool``).

Interfaces (relative names):
- publishes ``candidates`` (rollability_ros/CandidateResult, reliable, depth 1000): every evaluated candidate,
  after it is stored in the run's ``store.sqlite``;
- publishes ``generations`` (rollability_ros/GenerationSummary, latched): every completed generation, after its
  checkpoint; candidates and generations carry the node's ``session.id`` (``session``), so a session's
  outcome_logger stores only its own optimizer's;
- publishes ``optimizer_progress`` (rollability_ros/OptimizerProgress, latched): where the run stands (generations
  done, the run's cap, best so far, simulated trials evaluated), when a run starts or resumes and after every
  generation: what ``rollability study`` and ``bringup`` show, so they never open the run's store;
- publishes ``best_profile_marker`` (visualization_msgs/Marker TRIANGLE_LIST, latched): the best-so-far
  profile solid (metres) where it is mounted: in the chassis's ``base_link`` on its top (``robot.body_height_m``
  / 2 above the box centre) or, for a URDF robot, in ``urdf_robot.mount_link`` at the mount footprint
  (``footprint_offset_m``, turned by ``footprint_yaw_deg``); ``frame_id``, if set, names that frame instead;
  re-sent whenever the best-so-far design changes (DELETE when it is the flat baseline);
- services (std_srvs/Trigger): ``start`` (start a run, if ``autostart`` is false or the last run ended),
  ``pause`` (send no new evaluations; those in flight finish and are kept), ``resume`` (continue after a
  pause, or retry after evaluations failed), ``stop`` (finish and checkpoint the current generation, then end
  the run; a paused run is resumed for that);
- calls ``<any namespace>/evaluate_profile`` (rollability_ros/action/EvaluateProfile): every server of that
  type, rediscovered every ``evaluator_discovery_period_s``; one goal in flight per server; when fewer candidates
  are queued than servers are idle, a candidate's trials are split over them (``first_trial``) and merged.

Parameters: the namespaces ``optimizer`` (config/optimizer.yaml, config/paper.yaml; ``optimizer.method`` picks
CMA-ES or CMA-MAE), ``quality_diversity`` (the CMA-MAE archive), ``selection``, ``profile`` and ``printer`` (the
grid and printer of config/robot.yaml, overridden by the optimization file), all saved in
the run's ``config.yaml``; ``robot`` (the chassis: the marker's mount and the screen's robot); ``urdf_robot`` (a
URDF robot's config such as config/husky.yaml: when it names a mount link, the grid's ``length_m`` / ``width_m``
are its mount footprint's, as the evaluators' are, the marker sits on that mount and the screen uses it);
``stable_poses`` (the screen that ranks initial means when ``optimizer.initial_mean_screen`` > 0); and:
``run_id`` (empty = new ``opt-<date>-<time>``), ``resume`` (continue run ``run_id`` from its last checkpoint),
``autostart`` (start once the graph has been searched twice), ``exit_on_finish``, ``select_designs`` (choose
Mesh A, B, C when the run finishes), ``frame_id``, ``evaluator_timeout_s``, ``evaluator_max_attempts``,
``evaluator_retry_delay_s``, ``evaluator_discovery_period_s``; ``session.id``: goals carry it, and a result from an
evaluator of another session is refused (logged once, never scored) and that evaluator is not asked again.
Goals also carry the robot's print (``printed_with``: its ``profile_print`` and ``profile_mass_scale``, what the
designs file will tell the lab to print); an evaluator that weighs the profile otherwise rejects them.
Optimizer parameters are read when a run starts.
See docs/optimization.md.

A failed evaluation (rejected goal, aborted, silent for ``evaluator_timeout_s``, evaluator gone) is retried on
another evaluator and never scored; after ``evaluator_max_attempts`` failures of one candidate the run pauses
and says why (``resume`` retries the generation; with ``exit_on_finish`` the node exits with code 1 instead). Evaluators must use the same ``profile`` grid as this node
(their goals carry heights only). SIGINT / SIGTERM end the node at once; the run keeps its last checkpoint and
continues with ``resume:=true run_id:=<id>``.
"""
import dataclasses
import functools
import json
import math
import sys
import threading
import typing

import numpy

import numpy.typing as npt
import rclpy
from action_msgs.msg import GoalStatus
from geometry_msgs.msg import Point
from rclpy.exceptions import InvalidParameterValueException
from rclpy.action import get_action_names_and_types
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.node import Node
from std_srvs.srv import Trigger
from visualization_msgs.msg import Marker

from rollability_ros.action import EvaluateProfile
from rollability_ros.core.config import ConfigError, in_range, out_of_range
from rollability_ros.core.optimization import (EvaluationFailed, EvaluatorPool, GAIN_SOURCES, OptimizationRun,
                                               OptimizerSettings, PoolClosed, PoolSettings, QualityDiversitySettings,
                                               RunSettings, SelectionSettings, check_method_settings, profile_screen,
                                               run_config, run_generations, run_id_of, run_target, select_run,
                                               table_rows)
from rollability_ros.core.profile import PrinterSpec, ProfileGrid, is_baseline, marker_points, profile_mesh
from rollability_ros.core.robots import ChassisSpec, UrdfRobotSpec, footprint_grid, profile_mount
from rollability_ros.core.sim import ScreenSettings, world_fidelity
from rollability_ros.msg import CandidateResult, GenerationSummary, OptimizerProgress
from rollability_ros.nodes._convert import candidate_to_msg, generation_to_msg, progress_to_msg
from rollability_ros.nodes._support import (LATCHED_QOS, RECORD_QOS, ParameterError, SessionMembership,
                                            ThreadSafeActionClient, declare_settings, guard_settings,
                                            parameter_descriptor, read_settings, refusal, run_node)

#: The action type an evaluator serves (as the graph API names it).
EVALUATOR_ACTION_TYPE = "rollability_ros/action/EvaluateProfile"
#: Parameter namespaces that define a run and are saved in its config.yaml.
RUN_SECTIONS = {"optimizer": OptimizerSettings, "quality_diversity": QualityDiversitySettings,
                "selection": SelectionSettings, "profile": ProfileGrid, "printer": PrinterSpec}
#: Parameter namespaces of the robot the profile is for (the grid's footprint, the marker's mount) and of the
#: stable-pose screen of initial means on that robot; read when a run starts, not saved in its config.yaml.
ROBOT_SECTIONS = {"robot": ChassisSpec, "urdf_robot": UrdfRobotSpec, "stable_poses": ScreenSettings}
_STATUS_NAMES = {GoalStatus.STATUS_ABORTED: "aborted", GoalStatus.STATUS_CANCELED: "cancelled",
                 GoalStatus.STATUS_UNKNOWN: "unknown"}
_PARAMETERS: typing.Dict[str, typing.Tuple[typing.Any, ...]] = {  # name: (default, description[, inclusive range])
    "run_id": ("", "id of the run to start (empty: opt-<date>-<time>) or, with resume, to continue"),
    "resume": (False, "continue run run_id from its last checkpoint instead of starting a new run"),
    "autostart": (True, "start optimizing at start-up (false: wait for the start service)"),
    "select_designs": (False, "when the run finishes, choose designs A, B, C (section selection) into "
                              "<run>/designs/"),
    "exit_on_finish": (False, "end the node when the run ends: exit code 0 if it finished, 1 if it could not "
                              "start or got no real results (for unattended studies)"),
    "frame_id": ("", "frame of the best-profile marker; empty: the link the profile is mounted on (base_link of "
                     "the chassis, urdf_robot.mount_link of a URDF robot)"),
    "evaluator_discovery_period_s": (2.0, "s between searches of the graph for EvaluateProfile servers",
                                     (0.0, 3600.0), "low"),
}
#: The pool's settings the node declares as ``evaluator_<field>`` (description and range from PoolSettings).
_POOL_FIELDS = ("timeout_s", "max_attempts", "retry_delay_s")
_PARAMETERS.update({f"evaluator_{field.name}": (field.default, field.metadata["description"],
                                                field.metadata["range"], field.metadata.get("exclusive", ""))
                    for field in dataclasses.fields(PoolSettings) if field.name in _POOL_FIELDS})


def run_parameters(settings_by_section: typing.Mapping[str, typing.Any]) -> typing.Dict[str, typing.Any]:
    """Flat ``{"section.field": value}`` of the run-defining settings (what goes into the run's config.yaml)."""
    return {f"{prefix}.{name}": value for prefix, settings in settings_by_section.items()
            for name, value in dataclasses.asdict(settings).items()}


class Optimizer(Node):
    """Moves candidates and fitnesses between an :class:`OptimizationRun` and the evaluators in the graph."""

    def __init__(self):
        super().__init__("optimizer")
        for prefix, settings_cls in RUN_SECTIONS.items():
            declare_settings(self, prefix, settings_cls)
            guard_settings(self, prefix, settings_cls)
        self._robots: typing.Dict[str, typing.Any] = {}
        for prefix, settings_cls in ROBOT_SECTIONS.items():
            self._robots[prefix] = declare_settings(self, prefix, settings_cls)
            guard_settings(self, prefix, settings_cls,
                           on_change=functools.partial(self._robots.__setitem__, prefix))
        for name, (default, description, *declared) in _PARAMETERS.items():
            metadata = {"range": declared[0], "exclusive": declared[1] if len(declared) > 1 else ""} \
                if declared else None
            try:
                self.declare_parameter(name, default, parameter_descriptor(
                    description, declared[0] if declared else None, type(default), name=name,
                    exclusive=metadata["exclusive"] if metadata else ""))
            except InvalidParameterValueException as exc:
                raise ParameterError(refusal(name, exc, metadata)) from None
            if metadata is not None and not in_range(self._param(name), metadata):   # an open end
                raise ParameterError(out_of_range(name, self._param(name), metadata))
        pool_settings = PoolSettings(**{name: self._param(f"evaluator_{name}") for name in _POOL_FIELDS})
        discovery_period_s = self._param("evaluator_discovery_period_s")
        self._grid, self._mount = self._read_run_settings()["profile"], self._read_mount()
        self._session = SessionMembership(self)
        self._foreign: typing.Set[str] = set()   # evaluators that answered as another session's: never asked again
        self._printed_with = ""   # the run's print as JSON (start)

        self._candidates = self.create_publisher(CandidateResult, "candidates", RECORD_QOS)
        self._generations = self.create_publisher(GenerationSummary, "generations", LATCHED_QOS)
        self._progress = self.create_publisher(OptimizerProgress, "optimizer_progress", LATCHED_QOS)
        self._marker = self.create_publisher(Marker, "best_profile_marker", LATCHED_QOS)
        self._client_group = ReentrantCallbackGroup()
        self._action_clients = {}
        self._pool = EvaluatorPool(self._submit, pool_settings, log=self._log)
        self._lock = threading.Lock()
        self._worker = None
        self._stop_requested = threading.Event()
        self._best_heights = None
        self.exit_code = 0
        self.create_service(Trigger, "start", self._on_start)
        self.create_service(Trigger, "pause", self._run_control(self._pool.pause,
                                                                "paused: no new evaluations are sent"))
        self.create_service(Trigger, "resume", self._run_control(self._pool.resume, "resumed"))
        self.create_service(Trigger, "stop", self._run_control(
            self._request_stop, "stopping after the current generation is evaluated and checkpointed"))
        self._searches = 0
        self._autostart_pending = self._param("autostart")
        self.create_timer(discovery_period_s, self._discover)
        self.get_logger().info(f"ready: {self._grid.rows}x{self._grid.cols} grid, looking for "
                               f"{EVALUATOR_ACTION_TYPE} servers every {discovery_period_s:g} s")

    def _param(self, name):
        return self.get_parameter(name).value

    def _log(self, level, message):
        getattr(self.get_logger(), level)(message)

    # --- evaluators ----------------------------------------------------------------------------------------------
    def _discover(self):
        """Find the EvaluateProfile servers in the graph and hand the ready ones to the pool."""
        names = sorted(name for name, types in get_action_names_and_types(self) if EVALUATOR_ACTION_TYPE in types)
        for name in names:
            if name not in self._action_clients:
                self._action_clients[name] = ThreadSafeActionClient(self, EvaluateProfile, name,
                                                                    callback_group=self._client_group)
        ready = [name for name in names
                 if self._action_clients[name].server_is_ready() and name not in self._foreign]
        added, removed = self._pool.set_evaluators(ready)
        if added or removed:
            change = ", ".join([f"+{n}" for n in added] + [f"-{n}" for n in removed])
            self.get_logger().info(f"evaluators ({change}): {len(ready)} available")
        self._searches += 1
        if self._autostart_pending and self._searches >= 2:  # clients found in one search are ready by the next
            self._autostart_pending = False
            started, _message = self.start()
            if not started and self._param("exit_on_finish"):
                self.exit_code = 1
                rclpy.try_shutdown(context=self.context)

    def _submit(self, action_name, request, ticket):
        """Send one evaluation as an EvaluateProfile goal; report through ``ticket``; return a cancel function."""
        goal = EvaluateProfile.Goal(heights=list(request.heights), trials=request.trials, seed=request.seed,
                                    first_trial=request.first_trial, fidelity=request.fidelity,
                                    session=self._session.id,
                                    printed_with=self._printed_with)
        goal_handle = {}
        cancelled = threading.Event()

        def on_result(future: typing.Any) -> None:
            response = future.result()
            if response.status != GoalStatus.STATUS_SUCCEEDED:
                status = _STATUS_NAMES.get(response.status, f"status {response.status}")
                ticket.fail(f"goal {status}: {response.result.message or 'no message'}")
                return
            result = response.result
            refusal = self._session.refusal(result.session, f"result of evaluator {result.evaluator or action_name}")
            if refusal:   # never scored: retried on an evaluator of this session
                self._foreign.add(action_name)
                ticket.fail(refusal)
                return
            ticket.succeed(result.successes, result.trials, result.eval_time_s, result.evaluator or action_name,
                           trial_results=result.trial_results)   # a split request's parts are checked by them

        def on_goal_response(future: typing.Any) -> None:
            if future.exception() is not None:
                ticket.fail(f"sending the goal failed: {future.exception()!r}")
                return
            handle = future.result()
            if not handle.accepted:
                ticket.fail("goal rejected (that evaluator's log says why, e.g. a different profile grid or print)")
                return
            goal_handle["handle"] = handle
            ticket.progress()
            if cancelled.is_set():
                handle.cancel_goal_async()
                return
            handle.get_result_async().add_done_callback(on_result)

        def cancel() -> None:
            cancelled.set()
            handle = goal_handle.get("handle")
            if handle is not None:
                handle.cancel_goal_async()

        self._action_clients[action_name].send_goal_async(
            goal, feedback_callback=lambda _feedback: ticket.progress()).add_done_callback(on_goal_response)
        return cancel

    # --- services ------------------------------------------------------------------------------------------------
    def _on_start(self, _request, response):
        response.success, response.message = self.start()
        return response

    def _run_control(self, act, message):
        """A Trigger callback that calls ``act()`` if a run is in progress and answers ``message``."""
        def callback(_request: typing.Any, response: typing.Any) -> typing.Any:
            if not self.running:
                response.success, response.message = False, "no run in progress"
                return response
            act()
            response.success, response.message = True, message
            self.get_logger().info(message)
            return response
        return callback

    def _request_stop(self):
        self._stop_requested.set()
        self._pool.resume()   # a paused generation must finish to be checkpointed

    # --- the run -------------------------------------------------------------------------------------------------
    @property
    def running(self) -> bool:
        """True while a run's thread is alive."""
        return self._worker is not None and self._worker.is_alive()

    def start(self) -> typing.Tuple[bool, str]:
        """Start (or, with ``resume``, continue) a run in a worker thread; return ``(started, message)``."""
        with self._lock:
            if self.running:
                return False, "a run is already in progress"
            try:
                settings = self._read_run_settings()
                run_dir, parameters, resume = self._run_target(settings)
                check_method_settings(self._typed_run_settings(settings))
            except (ParameterError, ConfigError, ValueError, FileNotFoundError) as exc:
                self.get_logger().error(f"cannot start: {exc}")
                return False, str(exc)
            self._grid, self._mount = settings["profile"], self._read_mount()
            # every goal of the run names this print: an evaluator that weighs the profile otherwise refuses them
            self._printed_with = json.dumps(self._robot_settings(settings).print_instructions(), sort_keys=True)
            self._stop_requested.clear()
            self._pool.resume()
            self._worker = threading.Thread(target=self._optimize, name="optimization",
                                            args=(run_dir, parameters, resume, settings), daemon=True)
            self._worker.start()
            return True, f"{'resuming' if resume else 'starting'} run {run_id_of(run_dir)}"

    def _read_run_settings(self):
        """The run sections from the parameters, the grid spanning the robot's mount footprint (``footprint_grid``)."""
        settings: typing.Dict[str, typing.Any] = {prefix: read_settings(self, prefix, cls)
                                                  for prefix, cls in RUN_SECTIONS.items()}
        settings["profile"] = footprint_grid(settings["profile"], self._robots["urdf_robot"])
        return settings

    def _typed_run_settings(self, settings):
        """The :class:`~rollability_ros.core.optimization.optimizer_contract.RunSettings` of the sections this node
        declared (its own parse, once): what the method check and the start-point screen are handed."""
        return RunSettings(optimizer=settings["optimizer"],
                           quality_diversity=settings["quality_diversity"],
                           stable_poses=self._robots["stable_poses"], printer=settings["printer"])

    def _robot_settings(self, settings):
        """The evaluator settings of the profile's robot (grid, printer, robot sections) for the stable-pose screen."""
        from rollability_ros.core.sim import EvaluatorSettings

        return EvaluatorSettings(grid=settings["profile"], printer=settings["printer"], robot=self._robots["robot"],
                                 urdf_robot=self._robots["urdf_robot"])

    def _read_mount(self):
        """``(frame, position_m, yaw_deg)`` of the marker: the profile mount of the robot in use."""
        link, position_m, yaw_deg = profile_mount(self._robots["robot"], self._robots["urdf_robot"])
        return self._param("frame_id") or link, position_m, yaw_deg

    def _run_target(self, settings):
        """``(run_dir, parameters, resume)`` of the run to start, from ``run_id`` / ``resume``
        (:func:`~rollability_ros.core.optimization.run_directory.run_target`: a resume keeps the run's saved
        config.yaml with this node's run sections on top, so the core refuses one whose settings differ)."""
        resume = self._param("resume")
        run_dir, parameters = run_target(self._param("run_id"), resume, run_parameters(settings),
                                         settings["optimizer"].output_dir)
        return run_dir, parameters, resume

    def _optimize(self, run_dir, parameters, resume, settings):
        """The worker thread: run generations until a stop criterion, ``stop``, or shutdown; with
        ``exit_on_finish``, then end the node (exit code 0 when the run finished, 1 when it could not)."""
        code = self._run_to_end(run_dir, parameters, resume, settings)
        if code is not None and self._param("exit_on_finish"):
            self.exit_code = code
            rclpy.try_shutdown(context=self.context)

    def _run_to_end(self, run_dir, parameters, resume, settings):
        """Run (:func:`~rollability_ros.core.optimization.optimization_run.run_generations`); return 0 (finished or
        stopped), 1 (failed) or None (interrupted by shutdown)."""
        log = self.get_logger()
        try:
            run = OptimizationRun(
                run_dir, run_config(parameters), settings["profile"],
                self._pool.batch_evaluator(settings["optimizer"].trials),
                resume=resume, on_candidate=self._publish_candidate,
                # racing's stages (the only user of evaluate_trials) go whole, never split (docs/optimization.md)
                evaluate_trials=self._pool.fidelity_evaluator("", whole=True),
                screen_profiles=profile_screen(self._typed_run_settings(settings),
                                               self._robot_settings(settings)))
        except PoolClosed:   # shut down while the start means were evaluated (optimizer.initial_mean_measure)
            return None
        except (ConfigError, ValueError, FileNotFoundError, EvaluationFailed) as exc:
            log.error(f"cannot {'resume' if resume else 'start'} run in {run_dir}: {exc}")
            return 1
        try:
            log.info(f"{run.start_text(resume)}; {run.initial_mean_text()}")
            self._publish_best(run)
            self._publish_progress(run)
            run.on_generation = lambda record: self._publish_generation(record, run)
            end = run_generations(
                run, self._stop_requested.is_set, lambda exc: self._on_evaluation_failed(run, exc),
                evaluation_errors=(EvaluationFailed,), interruptions=(PoolClosed,))
            if end.status == "interrupted":
                self._log_interrupted(run)
            elif end.status == "failed":
                log.error(f"run {run.run_id}: {end.reason}; giving up (exit_on_finish)")
            else:
                log.info(run.end_text(end))
                if self._param("select_designs") and end.status == "finished" and end.result.best is not None:
                    self._select(run, settings)
            return end.exit_code
        except Exception as exc:  # a broken store or a bug must end the run loudly, not the node
            if not self.context.ok():   # shutting down: publishing failed because the context is gone
                self._log_interrupted(run)
                return None
            log.error(f"run {run.run_id} failed: {exc!r}")
            return 1
        finally:
            run.close()

    def _on_evaluation_failed(self, run, exc):
        """The node's policy for a generation without real results: give up with ``exit_on_finish``, else pause
        until the resume service (which retries the generation) or stop."""
        if self._param("exit_on_finish"):
            return False
        self._pool.pause()
        self.get_logger().error(f"generation {run.generation_number(run.optimizer.generation)} got no real results "
                                f"({exc}); paused: call the resume service to retry it, or stop")
        return True

    def _log_interrupted(self, run):
        self.get_logger().info(f"run {run.run_id} interrupted; its checkpoint holds {run.optimizer.generation} "
                               f"generation(s): continue with resume:=true run_id:={run.run_id}")

    def _select(self, run, settings):
        """Choose the designs of the finished run (paper 2.1.5) into ``<run_dir>/designs/``."""
        chosen = settings["selection"]
        evaluate_batch = self._pool.batch_evaluator(chosen.reevaluate_trials) if chosen.reevaluate_trials else None
        launch_batch = self._pool.fidelity_evaluator("launch") \
            if chosen.race_rounds or chosen.launch_trials else None
        robot = self._robot_settings(settings)

        def world_launch(heights_list: typing.List[numpy.ndarray], world_seed: int, launch_seed: int,
                         launches: int) -> typing.Sequence[typing.Tuple[int, int, float, str]]:
            """Launches in one world over the evaluators (fidelity world:<seed>) of each design's heights (a
            (grid.n_variables,) array each); their draws are the evaluators'."""
            return self._pool.fidelity_evaluator(world_fidelity(world_seed))(heights_list, launch_seed, launches)

        result, folder = select_run(run.store, run.run_id, run.run_dir, settings["profile"],
                                    settings["printer"], chosen, evaluate_batch, run.settings.seed,
                                    launch_batch, weigh=lambda mesh: robot.profile_body(mesh).mass_kg,
                                    world_launch=world_launch, printed_with=robot.print_instructions())
        rows = "; ".join(f"{row['configuration']} {row['simulated_fitness']:.3f}"
                         for row in table_rows(result) if row["trials"])
        self.get_logger().info(f"selected {len(result.designs)} design(s) into {folder} ({rows})"
                               + (f"; {result.shortfall}" if result.shortfall else ""))
        for gain in result.gains():
            if gain is not None:
                self.get_logger().info(f"{gain.label} minus the bare robot on {GAIN_SOURCES[gain.source]}: "
                                       f"{gain.text()} (95% Newcombe)")
        if result.no_design_helps():
            self.get_logger().warning(f"{result.no_design_helps()}; designs.yaml marks each design "
                                      f"beats_baseline: false")
        if result.recommendation is not None:
            self.get_logger().info(f"recommendation (simulated world check): {result.recommendation.headline()}")

    # --- publishing ----------------------------------------------------------------------------------------------
    def _publish_candidate(self, record):
        self._candidates.publish(candidate_to_msg(dataclasses.replace(record, session=self._session.id)))

    def _publish_generation(self, record, run):
        self._generations.publish(generation_to_msg(dataclasses.replace(record, session=self._session.id)))
        self._publish_progress(run)
        self._publish_best(run)
        self.get_logger().info(f"generation {record.generation}: best {record.best_fitness:.3f}, mean "
                               f"{record.mean_fitness:.3f}, best-so-far {record.best_so_far:.3f}, sigma "
                               f"{record.sigma:.4f}, {record.evaluations} evaluations")

    def _publish_progress(self, run):
        self._progress.publish(progress_to_msg(run.progress(), self.get_clock().now().nanoseconds / 1e9))

    def _publish_best(self, run):
        """Publish the best-so-far marker if the incumbent design changed since the last one published."""
        best = run.optimizer.best
        if best is None or (self._best_heights is not None and (best.heights == self._best_heights).all()):
            return
        self._best_heights = best.heights.copy()
        self._marker.publish(self.profile_marker(best.heights))

    def profile_marker(self, heights: npt.ArrayLike) -> typing.Any:
        """The Marker (TRIANGLE_LIST, metres) of the profile solid of ``heights`` ``(grid.n_variables,)`` (simulation
        units) on the robot's profile mount."""
        frame, position_m, yaw_deg = self._mount
        marker = Marker()
        marker.header.frame_id = frame
        marker.header.stamp = self.get_clock().now().to_msg()
        marker.ns, marker.id = "best_profile", 0
        marker.type = Marker.TRIANGLE_LIST
        mesh = None if is_baseline(heights, self._grid.flat_tolerance) else \
            profile_mesh(heights, self._grid)
        if mesh is None:
            marker.action = Marker.DELETE
            return marker
        marker.action = Marker.ADD
        marker.pose.position.x, marker.pose.position.y, marker.pose.position.z = (float(v) for v in position_m)
        marker.pose.orientation.z = math.sin(math.radians(yaw_deg) / 2)
        marker.pose.orientation.w = math.cos(math.radians(yaw_deg) / 2)
        marker.scale.x = marker.scale.y = marker.scale.z = 1.0
        marker.color.r, marker.color.g, marker.color.b, marker.color.a = 0.2, 0.6, 1.0, 0.9
        marker.points = [Point(x=x, y=y, z=z) for x, y, z in marker_points(mesh).tolist()]
        return marker

    def close(self) -> None:
        """End a run in progress at once (it keeps its last checkpoint) and wait for its thread."""
        self._pool.close()
        if self._worker is not None:
            self._worker.join(timeout=10)


def main(args: typing.Optional[typing.List[str]] = None) -> int:
    nodes = []

    def make() -> Optimizer:
        nodes.append(Optimizer())
        return nodes[-1]

    return run_node(make, args) or (nodes[-1].exit_code if nodes else 0)


if __name__ == "__main__":
    sys.exit(main())
