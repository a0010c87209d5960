"""Issue 43 item 3: one declaration per setting. The range in a settings field's ``metadata["range"]`` (with
``"exclusive"`` for an end it leaves out) is the only declaration, and the one builder every edge uses refuses a
value outside it in the same line whether it came from a parameter file given to the CLI
(:func:`~rollability_ros.core.config.load_parameters` then :func:`~rollability_ros.core.config.from_mapping`) or a
node's parameter (:func:`~rollability_ros.nodes._support.declare_settings`: rclpy's own range check, then the same
builder). A value at a closed end is accepted by both.

Table-driven over every ranged field of every settings dataclass in the package, found by walking its modules.
"""
import dataclasses
import importlib
import math
import pkgutil
import typing

import pytest
import yaml

import rollability_ros
from rollability_ros.core import config

#: The namespace every table row is given under, on both paths (the message names ``<namespace>.<field>``); any
#: namespace the parameter files know will do.
PREFIX = "robot"


def _settings_classes():
    """Every dataclass in the package with at least one field that declares ``metadata["range"]``."""
    found = {}
    for module_info in pkgutil.walk_packages(rollability_ros.__path__, "rollability_ros."):
        module = importlib.import_module(module_info.name)
        for value in vars(module).values():
            if (isinstance(value, type) and dataclasses.is_dataclass(value) and value.__module__ == module.__name__
                    and any("range" in field.metadata for field in dataclasses.fields(value))):
                found[f"{value.__module__}.{value.__qualname__}"] = value
    return [found[name] for name in sorted(found)]


def _ends(field_type, metadata):
    """``(end, outside, inside)`` for both ends: a value just outside the declared range, and one inside at that
    end (the bound itself when the end is closed)."""
    low, high = metadata["range"]
    exclusive = metadata.get("exclusive", "")
    rows = []
    for end, bound, outward in (("low", low, -1), ("high", high, +1)):
        is_open = exclusive in (end, "both")
        if field_type is int:
            step = 1
        else:
            step = 1e-6 * max(1.0, abs(bound))   # beyond rclpy's tolerance at a bound (rel 1e-6 > its 1e-9)
        cast = field_type
        rows.append((end, cast(bound) if is_open else cast(bound + outward * step),
                     cast(bound - outward * step) if is_open else cast(bound)))
    return rows


def _ranged_fields(settings_cls):
    """``(name, type, metadata)`` of each ranged field of ``settings_cls``."""
    hints = typing.get_type_hints(settings_cls)
    for field in dataclasses.fields(settings_cls):
        if "range" in field.metadata:
            assert hints[field.name] in (int, float), f"{settings_cls.__name__}.{field.name}: a range on a non-number"
            yield field.name, hints[field.name], field.metadata


CLASSES = _settings_classes()


def test_the_table_covers_every_ranged_field():
    """The walk finds the settings of every layer (the issue counted 163 ranged fields), nested ones included."""
    fields = [(cls, name) for cls in CLASSES for name, _type, _metadata in _ranged_fields(cls)]
    names = {cls.__name__ for cls, _ in fields}
    assert len(fields) >= 160, len(fields)
    assert {"OptimizerSettings", "QualityDiversitySettings", "PhysicsParams", "ValveConfig", "SerialRelayConfig",
            "ChassisSpec", "RecorderSettings", "TipMonitorNodeSettings"} <= names


def test_every_default_lies_in_its_declared_range():
    """A settings class built from nothing (every default) passes its own ranges."""
    for settings_cls in CLASSES:
        if all(f.default is not dataclasses.MISSING or f.default_factory is not dataclasses.MISSING
               for f in dataclasses.fields(settings_cls)):
            for field in dataclasses.fields(settings_cls):
                if "range" in field.metadata:
                    default = field.default if field.default is not dataclasses.MISSING else field.default_factory()
                    assert config.in_range(default, field.metadata), (settings_cls.__name__, field.name, default)


def _cli(settings_cls, values, tmp_path):
    """Build ``settings_cls`` the CLI's way from ``values`` (``{field: value}``): a parameter file, loaded and
    parsed; "" or the error's text."""
    path = tmp_path / "given.yaml"
    path.write_text(yaml.safe_dump({"/**": {"ros__parameters": {PREFIX: values}}}))
    flat = config.load_parameters([str(path)])
    try:
        config.from_mapping(settings_cls, config.section(flat, PREFIX), PREFIX)
    except config.ConfigError as exc:
        return str(exc)
    return ""


@pytest.fixture(scope="module")
def ros_context():
    import rclpy

    context = rclpy.Context()
    rclpy.init(context=context, args=[])
    yield context
    rclpy.shutdown(context=context)


def _node(settings_cls, values, context):
    """Build ``settings_cls`` the node's way: a node whose parameters ``<PREFIX>.<field>`` are overridden with
    ``values`` (``{field: value}``), declaring the settings (rclpy's descriptor check, then the builder); "" or the
    refusal's text."""
    import rclpy
    from rclpy.parameter import Parameter

    from rollability_ros.nodes._support import ParameterError, declare_settings

    node = rclpy.create_node("range_table", context=context, start_parameter_services=False,
                             parameter_overrides=[Parameter(f"{PREFIX}.{name}", value=value)
                                                  for name, value in values.items()])
    try:
        declare_settings(node, PREFIX, settings_cls)
    except ParameterError as exc:
        return str(exc)
    finally:
        node.destroy_node()
    return ""


def _range_refusal(message):
    return " out of range: " in message


@pytest.mark.parametrize("settings_cls", CLASSES, ids=lambda cls: cls.__name__)
def test_a_value_just_outside_is_refused_alike_and_the_ends_accepted(settings_cls, tmp_path, ros_context):
    """Each end of each ranged field: a value just outside gets the same line from the CLI and the node; the end
    itself (or a value just inside an open end) is let through by the range on both paths (a rule spanning fields
    may still refuse it, height_min at its top above height_max, but never as out of range)."""
    inside_ends = {"low": [], "high": []}
    for name, field_type, metadata in _ranged_fields(settings_cls):
        for end, outside, inside in _ends(field_type, metadata):
            expected = config.out_of_range(f"{PREFIX}.{name}", outside, metadata)
            assert _cli(settings_cls, {name: outside}, tmp_path) == expected
            assert _node(settings_cls, {name: outside}, ros_context) == expected
            assert not _range_refusal(_cli(settings_cls, {name: inside}, tmp_path))
            inside_ends[end].append((name, inside))
    for values in inside_ends.values():   # every field at that end at once: one node each
        assert not _range_refusal(_node(settings_cls, dict(values), ros_context))


@pytest.mark.parametrize("value, expected", [
    (math.nan, "robot.sigma0 out of range: nan is not in (0.0, 100.0]"),
    (math.inf, "robot.sigma0 out of range: inf is not in (0.0, 100.0]"),
    ("wide", "robot.sigma0: expected a number in (0.0, 100.0], got 'wide'"),
    (True, "robot.sigma0: expected a number in (0.0, 100.0], got True"),
])
def test_nan_infinity_and_a_wrong_type_get_one_line_alike(value, expected, tmp_path, ros_context):
    from rollability_ros.core.optimization import OptimizerSettings

    assert _cli(OptimizerSettings, {"sigma0": value}, tmp_path) == expected
    assert _node(OptimizerSettings, {"sigma0": value}, ros_context) == expected


def test_an_integer_setting_given_text_is_refused_alike(tmp_path, ros_context):
    from rollability_ros.core.optimization import OptimizerSettings

    expected = "robot.popsize: expected an integer in [2, 100000], got 'twelve'"
    assert _cli(OptimizerSettings, {"popsize": "twelve"}, tmp_path) == expected
    assert _node(OptimizerSettings, {"popsize": "twelve"}, ros_context) == expected


def test_core_entry_points_check_ranges_of_settings_built_in_code():
    """Settings built in code (not by a builder) are checked where the core takes them: their ranges, then the
    rules that span fields."""
    from rollability_ros.core.profile.geometry import PrinterSpec, ProfileGrid, design_space_printability

    with pytest.raises(config.ConfigError, match=r"^printer.nozzle_m out of range: 0.0 is not in \(0.0, 0.1\]$"):
        design_space_printability(ProfileGrid(), PrinterSpec(nozzle_m=0.0))
    with pytest.raises(config.ConfigError, match=r"^printer: printer.min_wall_m 0.20 mm is thinner than one"):
        design_space_printability(ProfileGrid(), PrinterSpec(min_wall_m=0.0002))
    assert design_space_printability(ProfileGrid(), PrinterSpec()) == []


def test_the_descriptor_says_an_open_end():
    from rollability_ros.nodes._support import parameter_descriptor

    descriptor = parameter_descriptor("a step", (0.0, 100.0), float, exclusive="low")
    assert descriptor.floating_point_range[0].from_value == 0.0
    assert descriptor.additional_constraints == "in (0.0, 100.0]"


def test_a_real_node_refuses_with_the_clis_line(ros_node, start_node):
    """One node process (not only the builder it uses): rclpy's own range refusal at start-up, reworded, is the
    CLI's line, and the node stops with exit code 2."""
    from rollability_ros.core.imu.tip_tracker import TipMonitorConfig

    with pytest.raises(config.ConfigError) as from_cli:
        config.from_mapping(TipMonitorConfig, {"tip_threshold_deg": 200.0}, "tip_monitor")
    assert str(from_cli.value) == "tip_monitor.tip_threshold_deg out of range: 200.0 is not in [0.0, 180.0)"
    process = start_node("tip_monitor", params={"tip_monitor.tip_threshold_deg": 200.0})
    assert ros_node.wait_for(lambda: not process.alive(), 30)
    assert process.process.returncode == 2 and str(from_cli.value) in process.log(), process.log()
