"""sim_evaluator: serves the EvaluateProfile action with PyBullet trials (``core.evaluation``).

Interfaces (relative names; run several side by side in different namespaces):
- action ``evaluate_profile`` (rollability_ros/action/EvaluateProfile): feedback per finished trial batch,
  cancel honoured between batches, result with fitness, Wilson interval and every trial's outcome. A goal with
  ``first_trial`` k runs trials k .. k + trials - 1 of the evaluation with its seed (a part of an evaluation the
  optimizer split over evaluators; the trial results keep those indices); k + trials above ``evaluator.max_trials``
  is rejected. The goal's
  ``fidelity`` picks what a trial is: empty or ``screen`` = the ``objective`` parameters, ``launch`` = robust
  launches on the launch twin, ``world:<seed>`` = those launches all in the one world drawn from ``seed`` (the
  plausible-world check) (``core/sim/objectives.py``, ``at_fidelity``); any other value is rejected. A goal
  whose ``printed_with`` (the optimizer's print, JSON) differs from this node's (``robot.profile_print`` and
  ``robot.profile_mass_scale``, or the URDF robot's) is rejected naming each difference: the fitness would be of
  another print than the designs file states.

- topic ``robot_description`` (std_msgs/String, transient local, as robot_state_publisher publishes it): the
  URDF when ``urdf_robot.mount_link`` names a mount and neither ``urdf_robot.urdf_path`` nor
  ``urdf_robot.robot_description`` is set; goals are rejected until a usable description has arrived, a bad one
  is logged and ignored.

Parameters: the namespaces of config/sim.yaml (``sim``, ``trial``), config/robot.yaml (``robot``, ``profile``,
``printer``), config/evaluator.yaml (``evaluator``) and a URDF robot's config (``urdf_robot``, e.g.
config/husky.yaml), each declared with a description and validated; an invalid ``ros2 param set`` is refused.
``evaluator.workers`` and ``evaluator.ray_address`` take effect at start; a worker count whose workers the machine's
available memory does not hold is refused there in one line (exit 2); mid-run, when a broken pool's replacement is
refused so, the goal is aborted naming the shortfall and each later goal first starts the configured pool again (or
is aborted so): never evaluated with fewer workers. ``session.id``: an evaluator of a session
rejects goals of another (logged once) and names its session in every result.
Goals are evaluated one at a time, each over the whole worker pool; bad goals are rejected with the reason logged.
"""
import dataclasses
import math
import sys
import threading
import typing

from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.node import Node
from std_msgs.msg import String

from rollability_ros.action import EvaluateProfile
from rollability_ros.core.sim import (SETTINGS_SECTIONS, EvaluationCancelled, EvaluatorSettings,
                                      TrialExecutor, TrialOutcome, check_fidelity, evaluate_profile, make_executor,
                                      request_problem, settings_at_fidelity, with_objective)
from rollability_ros.core.profile import check_heights, print_differences, print_instructions_from_text
from rollability_ros.msg import TrialResult
from rollability_ros.nodes._support import (LATCHED_QOS, ParameterError, SessionMembership, declare_settings,
                                            guard_settings, run_node)


class _CancelRequested:
    """Event-like view of a goal's cancel request or the node's stop, polled by the evaluation between batches."""

    def __init__(self, goal_handle, closing):
        self._goal_handle = goal_handle
        self._closing = closing

    def is_set(self) -> bool:
        return self._goal_handle.is_cancel_requested or self._closing.is_set()


def _trial_msgs(outcomes):
    return [TrialResult(index=o.index, seed=o.seed, upright=bool(o.upright), settled=bool(o.settled),
                        steps=int(o.steps), tilt_deg=float(o.tilt_deg)) for o in outcomes]


class SimEvaluator(Node):
    """Adapts :func:`rollability_ros.core.sim.evaluation.evaluate_profile` to the EvaluateProfile action."""

    def __init__(self):
        super().__init__("sim_evaluator")
        sections: typing.Dict[str, typing.Any] = {}   # field name -> its section's settings
        for field in dataclasses.fields(EvaluatorSettings):
            if field.name not in SETTINGS_SECTIONS:
                continue   # not a parameter section: the launch resolved from the objective's files (below)
            prefix = SETTINGS_SECTIONS[field.name]
            settings_cls = typing.cast(type, field.type)   # a class: the module has no string annotations
            sections[field.name] = declare_settings(self, prefix, settings_cls)
            guard_settings(self, prefix, settings_cls, on_change=self._setter(field.name))
        # the launch twin and conditions of the files the objective names, read here, once (and again when the
        # objective's files change): the core is handed them typed
        self._settings = with_objective(EvaluatorSettings(**sections), sections["objective"])
        self._session = SessionMembership(self)
        self._topic_description = ""
        if self._settings.urdf_robot.selected and not self._settings.urdf_robot.has_source:
            self.create_subscription(String, "robot_description", self._on_description, LATCHED_QOS)
        self._pool: typing.Optional[TrialExecutor] = None   # None: a replacement was refused (_start_pool)
        try:
            self._pool = make_executor(self._settings.evaluator)
        except ValueError as exc:   # e.g. a count the memory cannot hold: refused before any worker starts
            raise ParameterError(f"{self._pool_setting()}: {exc}") from exc
        self._busy = threading.Lock()
        self._closing = threading.Event()
        ActionServer(self, EvaluateProfile, "evaluate_profile", execute_callback=self._execute,
                     goal_callback=self._check_goal, cancel_callback=lambda _goal: CancelResponse.ACCEPT,
                     callback_group=ReentrantCallbackGroup())
        where = self._settings.evaluator.ray_address or f"{getattr(self._pool, 'workers', 1)} local worker(s)"
        self.get_logger().info(f"ready: evaluate_profile on {where}, grid "
                               f"{self._settings.grid.rows}x{self._settings.grid.cols}")

    def _setter(self, name):
        def apply(value: typing.Any) -> None:
            if name == "urdf_robot" and value.selected and not value.has_source and self._topic_description:
                value = dataclasses.replace(value, robot_description=self._topic_description)
            if name == "objective":   # a file that cannot be read refuses the change (ConfigError)
                self._settings = with_objective(self._settings, value)
            else:
                self._settings = dataclasses.replace(self._settings, **{name: value})
        return apply

    def _on_description(self, msg):
        urdf_robot = dataclasses.replace(self._settings.urdf_robot, robot_description=msg.data)
        try:
            if not msg.data.strip():   # validate() checks a description only when there is one: this took the node down
                raise ValueError("the message is empty")
            urdf_robot.validate()
        except ValueError as exc:
            self.get_logger().error(f"ignored robot_description: {exc}")
            return
        self._topic_description = msg.data
        self._settings = dataclasses.replace(self._settings, urdf_robot=urdf_robot)
        self.get_logger().info(f"robot description {urdf_robot.description().robot.name!r} received, "
                               f"profile on {urdf_robot.mount_link!r}")

    def goal_problem(self, goal: typing.Any) -> typing.Optional[str]:
        """Why ``goal`` cannot be evaluated, or None."""
        settings = self._settings
        if settings.urdf_robot.selected and not settings.urdf_robot.has_source:
            return "no robot description yet (waiting on the robot_description topic)"
        if check_fidelity(goal.fidelity):
            return check_fidelity(goal.fidelity)
        problem = request_problem(int(goal.trials), int(goal.first_trial), settings.evaluator.max_trials)
        if problem:
            return problem
        if len(goal.heights):
            if not all(math.isfinite(h) for h in goal.heights):
                return "heights contain NaN or infinity"
            try:
                check_heights(list(goal.heights), settings.grid)
            except ValueError as exc:
                return str(exc)
            if goal.printed_with:
                return self._print_problem(goal.printed_with)
        return None

    def _print_problem(self, printed_with: str) -> typing.Optional[str]:
        """Why a profile of a goal whose optimizer prints as ``printed_with`` (JSON) is not evaluated here, or None."""
        try:
            wanted = print_instructions_from_text(printed_with)
        except ValueError as exc:
            return f"printed_with: {exc}"
        differ = print_differences(wanted, self._settings.print_instructions(), ("optimizer", "this evaluator"))
        if differ:
            return (f"the optimizer prints the profile otherwise: {'; '.join(differ)}; start the evaluators with "
                    "the optimizer's parameter files (e.g. --config gradual_print)")
        return None

    def _check_goal(self, goal):
        if self._session.refusal(goal.session, "evaluate_profile goal"):
            return GoalResponse.REJECT
        problem = self.goal_problem(goal)
        if problem:
            self.get_logger().warning(f"rejected evaluate_profile goal: {problem}")
            return GoalResponse.REJECT
        return GoalResponse.ACCEPT

    def _execute(self, goal_handle):
        request = goal_handle.request
        progress = {"done": 0, "upright": 0}

        def on_trial(outcome: TrialOutcome) -> None:
            progress["done"] += 1
            progress["upright"] += int(outcome.upright)
            goal_handle.publish_feedback(EvaluateProfile.Feedback(trials_done=progress["done"],
                                                                  successes_so_far=progress["upright"]))

        result = EvaluateProfile.Result(evaluator=self.get_fully_qualified_name(), session=self._session.id)
        with self._busy:
            problem = self._start_pool()
            if problem:   # never evaluated on another pool (fewer workers, in-process) than configured
                goal_handle.abort()
                result.message = f"evaluation not started: {problem}"
                return result
            try:
                evaluation = evaluate_profile(list(request.heights) or None, request.trials, request.seed,
                                              settings_at_fidelity(self._settings, request.fidelity),
                                              executor=self._pool, on_trial=on_trial,
                                              cancel_event=_CancelRequested(goal_handle, self._closing),
                                              first_trial=request.first_trial)
            except EvaluationCancelled as exc:
                if goal_handle.is_cancel_requested:
                    goal_handle.canceled()
                else:
                    goal_handle.abort()   # the node is stopping: the client may retry elsewhere
                result.trials = len(exc.outcomes)
                result.successes = sum(o.upright for o in exc.outcomes)
                result.trial_results = _trial_msgs(exc.outcomes)
                result.message = str(exc) if goal_handle.is_cancel_requested else f"evaluator stopping: {exc}"
                return result
            except Exception as exc:  # a broken worker pool or physics error must not take the node down
                self.get_logger().error(f"evaluation failed: {exc!r}")
                problem = "" if self._closing.is_set() else self._replace_broken_pool()
                goal_handle.abort()
                result.message = f"evaluation failed: {exc}" + (f"; {problem}" if problem else "")
                return result
        goal_handle.succeed()
        result.fitness = evaluation.fitness
        result.successes = evaluation.successes
        result.trials = evaluation.trials
        result.ci_low = evaluation.ci_low
        result.ci_high = evaluation.ci_high
        result.eval_time_s = evaluation.eval_time_s
        result.trial_results = _trial_msgs(evaluation.trial_results)
        return result

    def _pool_setting(self) -> str:
        return "evaluator.ray_address" if self._settings.evaluator.ray_address else "evaluator.workers"

    def _replace_broken_pool(self) -> str:
        """Close the pool and start a new one; why none could start ("" when one did)."""
        try:
            if self._pool is not None:
                self._pool.close()
        except Exception as exc:
            self.get_logger().warning(f"closing the broken worker pool: {exc!r}")
        self._pool = None
        return self._start_pool()

    def _start_pool(self) -> str:
        """Start the configured pool when there is none; why it cannot start ("" when there is one).

        A replacement spawn_pool refuses (its workers need more memory than is available now) leaves no pool: each
        goal is aborted naming the shortfall until one starts, never evaluated with fewer workers than configured.
        """
        if self._pool is not None:
            return ""
        try:
            self._pool = make_executor(self._settings.evaluator)
        except Exception as exc:   # e.g. the memory refusal (ValueError): the node keeps serving
            problem = f"no worker pool: {self._pool_setting()}: {exc}"
            self.get_logger().error(problem)
            return problem
        return ""

    def close(self) -> None:
        """End a running evaluation at its next batch (the goal is aborted), then stop the worker processes."""
        self._closing.set()
        with self._busy:
            if self._pool is not None:
                self._pool.close()


def main(args: typing.Optional[typing.List[str]] = None) -> int:
    return run_node(SimEvaluator, args)


if __name__ == "__main__":
    sys.exit(main())
