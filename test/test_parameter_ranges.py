"""Every numeric ROS parameter of every node declares its inclusive range, read from the declarations themselves
(no node started, no DDS): the settings dataclasses each node passes to ``declare_settings`` (found in the node
modules' source) and the parameters a node declares directly. A value outside the range is refused in one line.

test_parameter_descriptions.py reads the same ranges over DescribeParameters from the running nodes.
"""
import ast
import dataclasses
import importlib
import pathlib
import typing

import pytest

NODES_DIR = pathlib.Path(__file__).resolve().parents[1] / "rollability_ros" / "nodes"


def _loop_sources(tree, variable):
    """The iterables that bind ``variable`` in a ``for`` loop of ``tree``: ``(kind, expression)`` pairs."""
    for node in ast.walk(tree):
        if not isinstance(node, ast.For):
            continue
        targets = node.target.elts if isinstance(node.target, ast.Tuple) else [node.target]
        if any(isinstance(t, ast.Name) and t.id == variable for t in targets):
            yield node.iter


def _declared_classes(module, tree, argument):
    """The settings dataclasses ``argument`` (the third argument of a ``declare_settings`` call) can be.

    Understood: a module-level name; the loop variable of ``for prefix, cls in TABLE.items()``; ``field.type``
    of ``for field in dataclasses.fields(Settings)``, also through a name assigned ``typing.cast(type,
    field.type)``. Anything else fails the test (it must not be skipped).
    """
    if isinstance(argument, ast.Name) and hasattr(module, argument.id):
        return [getattr(module, argument.id)]
    if isinstance(argument, ast.Name):
        for node in ast.walk(tree):
            if (isinstance(node, ast.Assign) and [ast.unparse(t) for t in node.targets] == [argument.id]
                    and isinstance(node.value, ast.Call) and ast.unparse(node.value.func) == "typing.cast"):
                return _declared_classes(module, tree, node.value.args[1])
    found = []
    if isinstance(argument, ast.Name):
        for source in _loop_sources(tree, argument.id):
            if (isinstance(source, ast.Call) and isinstance(source.func, ast.Attribute)
                    and source.func.attr == "items" and isinstance(source.func.value, ast.Name)):
                found.extend(getattr(module, source.func.value.id).values())
    elif isinstance(argument, ast.Attribute) and argument.attr == "type" and isinstance(argument.value, ast.Name):
        for source in _loop_sources(tree, argument.value.id):
            if isinstance(source, ast.Call) and ast.unparse(source.func) == "dataclasses.fields":
                owner = getattr(module, source.args[0].id)
                hints = typing.get_type_hints(owner)
                # the settings sections among the fields (a field that is not a settings dataclass, such as a
                # value resolved from them, is skipped by the node's loop and declares no parameter)
                found.extend(hints[f.name] for f in dataclasses.fields(owner)
                             if isinstance(hints[f.name], type) and dataclasses.is_dataclass(hints[f.name]))
    assert found, f"{module.__name__}: cannot tell which settings declare_settings({ast.unparse(argument)}) declares"
    return found


def node_settings():
    """``{node module: [settings dataclass, ...]}`` of every node module that declares settings."""
    declared = {}
    for path in sorted(NODES_DIR.glob("*.py")):
        if path.stem == "_support":
            continue
        tree = ast.parse(path.read_text(encoding="utf-8"))
        calls = [c for c in ast.walk(tree) if isinstance(c, ast.Call)
                 and ast.unparse(c.func).split(".")[-1] == "declare_settings" and len(c.args) >= 3]
        if calls:
            module = importlib.import_module(f"rollability_ros.nodes.{path.stem}")
            declared[path.stem] = [cls for call in calls for cls in _declared_classes(module, tree, call.args[2])]
    return declared


def numeric_fields(settings_cls, prefix=""):
    """``(dotted name, type, range or None)`` of every int / float field of ``settings_cls``, nested included."""
    hints = typing.get_type_hints(settings_cls)
    for field in dataclasses.fields(settings_cls):
        name = f"{prefix}.{field.name}" if prefix else field.name
        field_type = hints[field.name]
        if dataclasses.is_dataclass(field_type):
            yield from numeric_fields(field_type, name)
            continue
        optional = [a for a in typing.get_args(field_type) if a is not type(None)] \
            if typing.get_origin(field_type) is typing.Union else []
        if field_type in (int, float) or (len(optional) == 1 and optional[0] in (int, float)):
            yield name, field_type, field.metadata.get("range")


def test_every_numeric_parameter_of_every_node_declares_its_range():
    declared = node_settings()
    # every node module that declares settings is found, so none can drop out of the check unnoticed
    assert {"recorder", "player", "rig", "valve_controller", "sim_evaluator", "optimizer", "campaign_runner",
            "outcome_logger", "tip_monitor", "view_bridge"} <= set(declared)
    checked, missing = 0, []
    for node, classes in declared.items():
        for settings_cls in classes:
            for name, field_type, value_range in numeric_fields(settings_cls):
                checked += 1
                if value_range is None:
                    missing.append(f"{node}: {settings_cls.__name__}.{name} ({field_type})")
                else:
                    low, high = value_range
                    assert low <= high, f"{node}: {settings_cls.__name__}.{name}: empty range {value_range}"
    from rollability_ros.nodes import optimizer

    for name, (default, _description, *value_range) in optimizer._PARAMETERS.items():
        if type(default) in (int, float):
            checked += 1
            if not value_range:
                missing.append(f"optimizer: {name}")
    assert checked > 200 and not missing, missing


def test_the_recorders_size_and_time_parameters_have_ranges():
    """The ones the issue named."""
    from rollability_ros.core.bags.record_play import RecorderSettings

    ranges = {name: value_range for name, _type, value_range in numeric_fields(RecorderSettings)}
    for name in ("discovery_period_s", "split_max_bytes", "split_max_duration_s", "chunk_size_bytes"):
        assert ranges[name] is not None, name


def test_a_numeric_parameter_without_a_range_cannot_be_declared():
    from rollability_ros.nodes._support import parameter_descriptor

    with pytest.raises(TypeError, match="numeric parameter 'x.rate' declared without a range"):
        parameter_descriptor("a rate, Hz", None, float, name="x.rate")
    with pytest.raises(TypeError, match="declared without a range"):
        parameter_descriptor("a count", None, int)
    assert parameter_descriptor("a name", None, str).description == "a name"
    assert parameter_descriptor("a count", (0, 5), int).integer_range[0].to_value == 5


@pytest.mark.parametrize("name, value, expected", [
    ("recorder.chunk_size_bytes", 0, "recorder.chunk_size_bytes out of range: 0 is not in [1, 1073741824]"),
    ("recorder.discovery_period_s", -1.0, "recorder.discovery_period_s out of range: -1.0 is not in (0.0, 3600.0]"),
])
def test_a_value_outside_its_range_is_refused_in_one_line(name, value, expected):
    """Against rclpy's own range check (an in-process node: no process started)."""
    import rclpy
    from rclpy.parameter import Parameter

    from rollability_ros.core.bags.record_play import RecorderSettings
    from rollability_ros.nodes._support import ParameterError, declare_settings

    context = rclpy.Context()
    rclpy.init(context=context, args=[])
    try:
        node = rclpy.create_node("range_check", context=context, parameter_overrides=[Parameter(name, value=value)])
        try:
            with pytest.raises(ParameterError) as refused:
                declare_settings(node, "recorder", RecorderSettings)
        finally:
            node.destroy_node()
    finally:
        rclpy.shutdown(context=context)
    assert str(refused.value) == expected
