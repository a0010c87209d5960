"""ROS plumbing shared by the recorder and player nodes: QoS profiles, message classes, string-array parameters."""
import importlib
import typing

from rcl_interfaces.msg import ParameterDescriptor
from rclpy.exceptions import ParameterUninitializedException
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from rollability_ros.core.bags import split_type_name
from rollability_ros.nodes._support import ParameterError


def qos_profile_from_dict(qos: typing.Mapping[str, typing.Any]) -> QoSProfile:
    """rclpy ``QoSProfile`` from a :mod:`rollability_ros.core.bags.qos` dict (history, depth, reliability,
    durability; deadline, lifespan and liveliness stay at their defaults, which match any peer)."""
    return QoSProfile(history=HistoryPolicy[qos["history"].upper()], depth=max(1, int(qos["depth"])),
                      reliability=ReliabilityPolicy[qos["reliability"].upper()],
                      durability=DurabilityPolicy[qos["durability"].upper()])


_Checked = typing.TypeVar("_Checked")


def declare_string_list(node: Node, name: str, description: str,
                        check: typing.Callable[[typing.List[str]], _Checked]) -> _Checked:
    """Declare string-array parameter ``name`` (default empty) and return ``check(values)``.

    ``check`` turns the list into the value the node uses and raises ``ValueError`` naming the problem,
    reported as a :class:`ParameterError` naming the parameter.
    """
    node.declare_parameter(name, Parameter.Type.STRING_ARRAY, ParameterDescriptor(description=description))
    try:
        values = list(node.get_parameter(name).value)
    except ParameterUninitializedException:   # declared with a type and no value: the empty default
        values = []
    try:
        return check(values)
    except ValueError as exc:
        raise ParameterError(f"{name}: {exc}") from exc


def message_class(type_name: str) -> typing.Any:
    """Import the Python class of ``pkg/msg/Type``; ``ValueError`` when the package's interfaces are not installed."""
    package, kind, name = split_type_name(type_name)
    try:
        return getattr(importlib.import_module(f"{package}.{kind}"), name)
    except (ImportError, AttributeError) as exc:
        raise ValueError(f"type {type_name} is not importable here ({exc}); install its interface package") from exc


def parameter_overrides(values: typing.Mapping[str, typing.Any]) -> typing.List[Parameter]:
    """rclpy ``Parameter`` overrides from ``{name: value}``, leaving out unset (None) and empty-list values."""
    return [Parameter(name, value=value) for name, value in values.items() if value is not None and value != []]
