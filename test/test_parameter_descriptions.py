"""What `ros2 param describe` shows for every node, read over ROS (rcl_interfaces ListParameters and
DescribeParameters services of each running node): a description with meaning and units, not the name again;
numeric ranges where they exist; start-up-only parameters read-only."""
import os
import re

#: node module -> parameters it needs to start here (files go to the test's tmp_path)
NODES = {
    "valve_controller": {"valve.backend": "dry_run"},
    "rig": {"rig.backend": "physical"},
    "outcome_logger": {"store_path": "{tmp}/store.sqlite"},
    "recorder": {"recorder.output_dir": "{tmp}/bag"},
    "player": {"player.bag": os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "bags",
                                          "sample")},
    "tip_monitor": {},
    "view_bridge": {},
    "sim_evaluator": {"evaluator.workers": 1},
    "optimizer": {"autostart": False},
    "campaign_runner": {"runner.store_path": "{tmp}/runner.sqlite", "runner.server_timeout_s": 600.0},
}
#: node module -> ROS arguments. The campaign_runner waits for a logger that never comes (a remapped service), so
#: it stays up to be described instead of sending (unsigned, refused) goals to the physical rig and exiting.
ROS_ARGS = {"campaign_runner": ["-r", "stored_trials:=/nowhere/stored_trials"]}

#: numeric parameters that may carry no range, each with the reason no bound exists (none today: every integer and
#: floating-point parameter of every node declares its inclusive range, issue 29)
UNBOUNDED = {}

#: words that carry no meaning of their own
_FILLER = {"the", "a", "an", "of", "in", "to", "for", "and", "or", "per", "is", "be", "as", "by", "on", "at"}

#: parameter-name unit suffix -> words one of which the description must contain
UNIT_WORDS = {"m": ("m", "metre", "metres", "meter", "meters"), "s": ("s", "second", "seconds"),
              "ms": ("ms", "millisecond", "milliseconds"), "deg": ("deg", "degree", "degrees"),
              "mps": ("m/s",), "mps2": ("m/s^2", "m/s2"), "radps": ("rad/s",), "hz": ("hz",), "kg": ("kg",),
              "n": ("n", "newton", "newtons"), "nm": ("n m", "nm", "n·m"), "kgpm3": ("kg/m^3", "kg/m3"),
              "psi": ("psi",), "bar": ("bar",), "pa": ("pa",)}


def words(text):
    return [w for w in re.findall(r"[a-z0-9]+", text.lower()) if w not in _FILLER]


def restates_name(name, description):
    """True when the description adds no word to the parameter's own name (its leaf and prefix)."""
    return not description.strip() or set(words(description)) <= set(words(name.replace(".", " ").replace("_", " ")))


def missing_unit(name, description):
    """The unit word the description lacks for a name ending in a unit suffix (``_m``, ``_s``, ...), or ''."""
    suffix = name.rsplit("_", 1)[-1] if "_" in name.rsplit(".", 1)[-1] else ""
    accepted = UNIT_WORDS.get(suffix)
    if not accepted:
        return ""
    text = " " + re.sub(r"[,;()]", " ", description.lower()) + " "
    return "" if any(f" {unit} " in text or f" {unit}," in text or f"({unit}" in description.lower()
                     or f"{unit}." in text for unit in accepted) else suffix


def describe_node(ros_node, node_name, timeout_s=60.0):
    """``{name: ParameterDescriptor}`` of a running node, through its parameter services."""
    from rcl_interfaces.srv import DescribeParameters, ListParameters

    listing = ros_node.node.create_client(ListParameters, f"/{node_name}/list_parameters")
    describe = ros_node.node.create_client(DescribeParameters, f"/{node_name}/describe_parameters")
    assert listing.wait_for_service(timeout_sec=timeout_s) and describe.wait_for_service(timeout_sec=timeout_s)
    names = _call(ros_node, listing, ListParameters.Request()).result.names
    request = DescribeParameters.Request()
    request.names = list(names)
    return dict(zip(names, _call(ros_node, describe, request).descriptors))


def _call(ros_node, client, request):
    future = client.call_async(request)
    assert ros_node.wait_for(future.done, 30)
    return future.result()


def test_every_node_parameter_is_described_with_meaning_units_and_ranges(ros_node, start_node, tmp_path):
    started = {module: start_node(module, params={k: v.format(tmp=tmp_path) if isinstance(v, str) else v
                                                  for k, v in params.items()}, ros_args=ROS_ARGS.get(module, ()))
               for module, params in NODES.items()}
    from rcl_interfaces.msg import ParameterType

    described, restating, unitless, unranged = {}, [], [], []
    for module, process in started.items():
        descriptors = describe_node(ros_node, module)
        assert process.alive(), process.log()
        for name, descriptor in descriptors.items():
            if name in ("use_sim_time", "start_type_description_service") or name.startswith("qos_overrides."):
                continue          # rclpy's own
            described[f"{module}:{name}"] = descriptor
            if restates_name(name, descriptor.description):
                restating.append(f"{module}:{name}: {descriptor.description!r}")
            if missing_unit(name, descriptor.description):
                unitless.append(f"{module}:{name}: {descriptor.description!r}")
            numeric = descriptor.type in (ParameterType.PARAMETER_INTEGER, ParameterType.PARAMETER_DOUBLE)
            if numeric and not (descriptor.floating_point_range or descriptor.integer_range) \
                    and f"{module}:{name}" not in UNBOUNDED:
                unranged.append(f"{module}:{name}")
    ranged = sum(1 for d in described.values() if d.floating_point_range or d.integer_range)
    read_only = sum(1 for d in described.values() if d.read_only)
    print(f"\n{len(described)} node parameters described over ROS: {len(restating)} restate the name, "
          f"{len(unitless)} lack their unit, {ranged} carry a numeric range, {len(unranged)} numeric ones do not, "
          f"{read_only} read-only")
    assert restating == [], "\n".join(restating)
    assert unitless == [], "\n".join(unitless)
    assert unranged == [], "numeric parameters without a range (add metadata['range']):\n" + "\n".join(unranged)
    assert ranged >= 40 and read_only >= 10
    tip = described["tip_monitor:tip_monitor.tip_threshold_deg"]
    assert tip.floating_point_range[0].from_value == 0.0 and tip.floating_point_range[0].to_value == 180.0
    assert described["tip_monitor:diagnostics_period_s"].read_only


def test_the_restating_check_catches_what_the_issue_found():
    assert restates_name("valve.max_pulse_ms", "max pulse ms")
    assert restates_name("rig.countdown_s", "countdown s")
    assert not restates_name("valve.max_pulse_ms", "longest valve opening the controller allows, ms; longer "
                                                   "fire requests are cut")
    assert missing_unit("valve.max_pulse_ms", "longest valve opening") == "ms"
    assert missing_unit("valve.max_pulse_ms", "longest valve opening, ms") == ""
