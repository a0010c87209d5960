"""The project's node graph as command lines: which node, in which namespace, with which parameter files.

Every node gets the same ordered list of ROS 2 parameter files (``--params-file``, later files override earlier
ones; a node takes only the parameters it declares), plus a few per-node overrides (``-p name:=value``). The CLI
reads the same files with :func:`rollability_ros.core.config.load_parameters`, so a value means the same to a
node and to a verb.
"""
import dataclasses
import sys

from rollability_ros.core.config import resolve_config_path
from rollability_ros.core.graph.supervisor import ProcessSpec

#: Parameter files every node of the main job reads, in order (later ones override earlier ones).
DEFAULT_CONFIGS = ("sim", "robot", "evaluator", "launch_twin", "rig", "campaign", "optimizer")


def _ros_value(value):
    """A parameter value as ``-p name:=value`` text (YAML for the ROS argument parser)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_ros_value(item) for item in value) + "]"
    if isinstance(value, str):
        return "'" + value.replace("'", "''") + "'"
    return repr(value)


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

    def ros_args(self, param_files):
        """The node's arguments: ``--ros-args``, name and namespace remaps, parameter files, overrides."""
        args = ["--ros-args"]
        if self.name:
            args += ["-r", f"__node:={self.name}"]
        if self.namespace:
            args += ["-r", f"__ns:={self.namespace}"]
        for path in param_files:
            args += ["--params-file", path]
        for key, value in self.params.items():
            args += ["-p", f"{key}:={_ros_value(value)}"]
        return args

    def argv(self, param_files, python=sys.executable):
        """The command line: ``python -m rollability_ros.nodes.<module>`` and :meth:`ros_args`."""
        return [python, "-m", f"rollability_ros.nodes.{self.module}", *self.ros_args(param_files)]

    def process_spec(self, param_files):
        """A :class:`~rollability_ros.core.graph.supervisor.ProcessSpec` for the supervisor."""
        return ProcessSpec(name=self.label or self.name or self.module, argv=self.argv(param_files), restart=self.restart, critical=self.critical,
                           stop_timeout_s=self.stop_timeout_s)


def parameter_files(extra=()):
    """Resolved paths of :data:`DEFAULT_CONFIGS` followed by ``extra`` (names of shipped files or paths)."""
    return [resolve_config_path(name) for name in (*DEFAULT_CONFIGS, *extra)]
