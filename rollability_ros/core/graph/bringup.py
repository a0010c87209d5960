"""The node graph of a lab session as command lines: which nodes ``rollability bringup``, ``rollability study`` and
the ROS launch files start, in which namespace, with which parameter files.

Settings come from ``config/bringup.yaml`` (namespace ``bringup``). The graph: recorder (MCAP bag),
outcome_logger (durable store), valve_controller, N sim_evaluator nodes (namespaces ``/eval_<i>``), and on
request the optimizer, the rig and the live-view bridge.

Every node gets the same ordered list of ROS 2 parameter files (``--params-file``, later files override earlier
ones; a node takes only the parameters it declares; :func:`parameter_files`), plus a few per-node overrides,
written as one more parameter file after them (:func:`override_file`). The CLI reads the same files with
:func:`rollability_ros.core.config.load_parameters`, so a value means the same to a node and to a verb.

Why a file and not ``-p name:=value``: in ROS 2 Jazzy (rcl), a parameter that two ``--params-file`` files both set
is kept twice, the later file's value wins, and a ``-p`` override replaces only the first of the two. So a user's
file that repeats, say, ``valve.backend`` or ``optimizer.output_dir`` (or a shipped file named twice with
``--config``) silently beat the graph's own override. The last file's value always wins, so the overrides go last.
"""
import dataclasses
import datetime
import os
import sys
import typing

import yaml

from rollability_ros.core.config import (check_parent_steps, edge_parse, from_mapping, load_parameters,
                                         parameter_document, resolve_config_path, section)
from rollability_ros.core.graph.supervisor import ProcessSpec
from rollability_ros.core.optimization import atomic_write_bytes

#: Parameter files every node of the main job reads, in order (later ones override earlier ones).
DEFAULT_CONFIGS = ("sim", "robot", "evaluator", "launch_twin", "rig", "campaign", "optimizer")


#: Folder, inside a study or session directory, of the per-node override files (:func:`override_file`).
NODE_PARAMS_DIR = "node-params"


def override_file(directory: str, label: str, params: typing.Mapping[str, object]) -> str:
    """Write ``params`` (``{"section.name": value}``) as the ROS 2 parameter file
    ``<directory>/node-params/<label>.yaml`` (for every node, ``/**``; nested, since a dotted key in a file does not
    override the same parameter nested in an earlier file) and return its path (module docstring)."""
    path = os.path.join(directory, NODE_PARAMS_DIR, f"{label}.yaml")
    os.makedirs(os.path.dirname(path), exist_ok=True)
    text = yaml.safe_dump(parameter_document(params), sort_keys=False)
    atomic_write_bytes(path, text.encode("utf-8"))   # a restarted node never reads half a file
    return path


@dataclasses.dataclass
class NodeLaunch:
    """One node process: ``module`` in ``rollability_ros.nodes``, its name, namespace, files and overrides.

    ``label`` names the process for the supervisor and its log file (default: the node name or module).
    """

    module: str
    label: str = ""
    name: str = ""
    namespace: str = ""
    params: dict = dataclasses.field(default_factory=dict)
    restart: bool = True
    critical: bool = True
    stop_timeout_s: float = 15.0

    @property
    def process_label(self) -> str:
        """The supervisor's name for the process (and of its log and override files)."""
        return self.label or self.name or self.module

    def ros_args(self, param_files: typing.Sequence[str], params_dir: str) -> typing.List[str]:
        """The node's arguments: ``--ros-args``, name and namespace remaps, parameter files, and last its
        overrides as a file written under ``params_dir`` (the study's or session's directory; :func:`override_file`)."""
        args = ["--ros-args"]
        if self.name:
            args += ["-r", f"__node:={self.name}"]
        if self.namespace:
            args += ["-r", f"__ns:={self.namespace}"]
        for path in param_files:
            args += ["--params-file", path]
        if self.params:
            args += ["--params-file", override_file(params_dir, self.process_label, self.params)]
        return args

    def argv(self, param_files: typing.Sequence[str], params_dir: str, python: str = sys.executable
             ) -> typing.List[str]:
        """The command line: ``python -m rollability_ros.nodes.<module>`` and :meth:`ros_args`."""
        return [python, "-m", f"rollability_ros.nodes.{self.module}", *self.ros_args(param_files, params_dir)]

    def process_spec(self, param_files: typing.Sequence[str], params_dir: str) -> ProcessSpec:
        """A :class:`~rollability_ros.core.graph.supervisor.ProcessSpec` for the supervisor."""
        return ProcessSpec(name=self.process_label, argv=self.argv(param_files, params_dir), restart=self.restart,
                           critical=self.critical, stop_timeout_s=self.stop_timeout_s)


#: The parameter that names the valve session key file, per node module that reads it.
KEY_FILE_PARAMETERS = {"valve_controller": "valve.session_key_file", "rig": "valve.session_key_file",
                       "outcome_logger": "session_key_file", "campaign_runner": "runner.session_key_file"}


def join_nodes(nodes: typing.Iterable[NodeLaunch], session_id: str, key_file: str) -> None:
    """Make every node of ``nodes`` a member of session ``session_id`` (``session.id``: they talk only to nodes of
    the same session) and give those that read the valve session key the session's own ``key_file``."""
    for node in nodes:
        node.params["session.id"] = session_id
        if node.module in KEY_FILE_PARAMETERS:
            node.params[KEY_FILE_PARAMETERS[node.module]] = key_file


def parameter_files(extra: typing.Sequence[str] = ()) -> typing.List[str]:
    """Resolved paths of :data:`DEFAULT_CONFIGS` followed by ``extra`` (names of shipped files or paths)."""
    return [resolve_config_path(name) for name in (*DEFAULT_CONFIGS, *extra)]


@dataclasses.dataclass
class GraphSettings:
    """``bringup.*`` (config/bringup.yaml): how many evaluators, what to record and serve."""

    namespace: str = "/rollability"
    evaluators: int = 2
    evaluator_workers: int = 1
    record: bool = True
    view: bool = False
    view_port: int = 8765
    output_dir: str = "runs"
    optimization_timeout_s: float = 0.0
    campaign_timeout_s: float = 0.0
    poll_period_s: float = 2.0

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first unusable field."""
        if not self.namespace.startswith("/") or "//" in self.namespace or self.namespace.endswith("/") and \
                self.namespace != "/":
            raise ValueError(f"namespace must be an absolute ROS namespace such as /rollability, got {self.namespace!r}")
        if not 0 <= self.evaluators <= 64:
            raise ValueError(f"evaluators must be in [0, 64] (0: a rig-only session), got {self.evaluators}")
        if self.evaluator_workers < 0:
            raise ValueError(f"evaluator_workers must be >= 0 (0 = one per core), got {self.evaluator_workers}")
        if not 0 < self.view_port < 65536:
            raise ValueError(f"view_port must be a TCP port, got {self.view_port}")
        if self.optimization_timeout_s < 0 or self.campaign_timeout_s < 0 or self.poll_period_s <= 0:
            raise ValueError("timeouts must be >= 0 (0 = none) and poll_period_s > 0")
        check_parent_steps(self.output_dir, "bringup.output_dir")   # before any folder is made or node started


#: Keys of ``bringup.*`` that moved: old key -> the one key that sets it now.
MOVED_KEYS = {"valve_backend": "valve.backend"}


@edge_parse
def load_graph_settings(param_files: typing.Sequence[str]) -> "GraphSettings":
    """:class:`GraphSettings` from the merged parameter files (namespace ``bringup``).

    A key of :data:`MOVED_KEYS` is refused naming the key that replaced it: one setting picks the valve's backend
    (``valve.backend``, read by the valve_controller node itself), so a lab file that still sets
    ``bringup.valve_backend`` must not be silently ignored or beat it."""
    values = section(load_parameters(param_files), "bringup")
    for old, new in MOVED_KEYS.items():
        if old in values:
            raise ValueError(f"bringup.{old} is no longer read: set {new} instead (config/rig.yaml; one key picks "
                             f"it for bringup, study, the launch files and the valve_controller node)")
    return from_mapping(GraphSettings, values, "bringup")


def new_study_id(now: typing.Optional[datetime.datetime] = None) -> str:
    """``study-<UTC date>-<time>``: sortable and unique per second."""
    now = now or datetime.datetime.now(datetime.timezone.utc)
    return now.strftime("study-%Y%m%d-%H%M%S")


def core_nodes(settings: "GraphSettings", study_dir: str,
               bag_dir: typing.Optional[str] = None, evaluators: bool = True) -> typing.List[NodeLaunch]:
    """The always-on part of the graph: recorder, outcome_logger, valve_controller, evaluators (unless
    ``evaluators`` is False: only an optimizer asks them for work).

    The recorder writes ``bag_dir`` (default ``<study_dir>/bag``); the logger's store is
    ``<study_dir>/``:data:`SESSION_STORE`, the file ``rollability report <study_dir>`` reads.
    """
    nodes = []
    namespace = settings.namespace.rstrip("/")
    if settings.record:
        nodes.append(NodeLaunch("recorder", params={"recorder.output_dir": bag_dir or os.path.join(study_dir, "bag")},
                                stop_timeout_s=30.0))
    nodes.append(NodeLaunch("outcome_logger", params={"store_path": os.path.join(study_dir, "outcomes.sqlite")}))
    nodes.append(NodeLaunch("valve_controller"))   # valve.backend from the parameter files: the one key
    for index in range(settings.evaluators if evaluators else 0):
        nodes.append(NodeLaunch("sim_evaluator", label=f"eval_{index}", namespace=f"{namespace}/eval_{index}",
                                params={"evaluator.workers": settings.evaluator_workers}))
    if settings.view:
        nodes.append(NodeLaunch("view_bridge", params={"port": settings.view_port}, critical=False))
    for node in nodes:
        node.namespace = node.namespace or settings.namespace
    return nodes


#: The nodes that run the launch twin, and the parameter listing the twin's files for each.
TWIN_CONFIG_PARAMETERS = {"rig": "rig.twin_config", "sim_evaluator": "objective.twin_config",
                          "optimizer": "objective.twin_config"}


def add_twin_files(nodes: typing.Sequence[NodeLaunch], param_files: typing.Sequence[str],
                   given_files: typing.Sequence[str]) -> None:
    """Append each of the user's ``given_files`` that sets launch twin parameters to the twin file list of every
    node in ``nodes`` that runs the twin (:data:`TWIN_CONFIG_PARAMETERS`; the list as ``param_files`` or the node's
    own overrides set it, else the shipped twin files), so every twin of the session reads them: applied, never
    dropped because the twin reads only its own list."""
    from rollability_ros.core.rig import RigSettings
    from rollability_ros.core.sim import twin_files

    extra = twin_files(given_files)
    if not extra:
        return
    merged = load_parameters(list(param_files))
    for node in nodes:
        name = TWIN_CONFIG_PARAMETERS.get(node.module)
        if name is not None:
            twin = list(node.params.get(name, merged.get(name, RigSettings().twin_config)))
            node.params[name] = [*twin, *(path for path in extra if path not in twin)]


def session_nodes(settings: "GraphSettings", run_dir: str, rig_backend: str = "sim",
                  optimizer: bool = True) -> typing.List[NodeLaunch]:
    """A lab session's graph: :func:`core_nodes`, the rig (``sim`` | ``physical``) and optionally the optimizer.

    Without the optimizer no sim_evaluator starts (nothing else asks them for work). The optimizer waits for its
    ``start`` service (no autostart) and keeps its runs under ``run_dir``.
    """
    nodes = core_nodes(settings, run_dir, evaluators=optimizer)   # evaluators serve only the optimizer
    nodes.append(NodeLaunch("rig", namespace=settings.namespace, params={"rig.backend": rig_backend}))
    if optimizer:
        nodes.append(NodeLaunch("optimizer", namespace=settings.namespace,
                                params={"optimizer.output_dir": run_dir, "autostart": False}))
    return nodes
