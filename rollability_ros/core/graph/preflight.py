"""Check every node's parameters before a graph starts, so a bad value stops a study at once with its reason.

Each node validates its own parameters at start-up (``declare_settings``), but inside a supervised graph that
reason lands in the node's log while the rest of the graph runs on. :func:`check_graph_parameters` builds the
same settings dataclasses from the same parameter files, for each node name as the node would see them
(``/**`` plus its own section), and collects every problem as ``"<node>: <prefix>.<field>: <reason>"``.
Parameters a node declares outside these dataclasses (topic lists, run ids) are not checked here.

A dotted parameter in a namespace these dataclasses read (``objective.``, ``optimizer.``, ...) that is a field of
none of them is refused too (:func:`unknown_parameters`): no node reads it, so a misspelt key or one written for
another version of the package would otherwise be dropped without a word (rclpy ignores a parameter file's
undeclared names) and the graph would run on the default instead.
"""
import dataclasses
import functools
import typing

from rollability_ros.core.config import ConfigError, check_given_files, edge_parse, from_mapping, load_parameters, section


def _node_sections():
    """``{node name: {parameter prefix: settings dataclass}}`` of the nodes a study starts."""
    from rollability_ros.core.bags import RecorderSettings
    from rollability_ros.core.config import SessionSettings
    from rollability_ros.core.campaign import CampaignSpec, RunnerSettings
    from rollability_ros.core.imu import ImuOutcomeConfig
    from rollability_ros.core.optimization import OptimizerSettings, QualityDiversitySettings, SelectionSettings
    from rollability_ros.core.profile import PrinterSpec, ProfileGrid
    from rollability_ros.core.results import OutcomeLoggerSettings
    from rollability_ros.core.rig import RigSettings, SpeedGateConfig, ValveConfig
    from rollability_ros.core.robots import ChassisSpec, UrdfRobotSpec
    from rollability_ros.core.sim import SETTINGS_SECTIONS, EvaluatorSettings, ScreenSettings

    hints = typing.get_type_hints(EvaluatorSettings)
    evaluator = {prefix: hints[field] for field, prefix in SETTINGS_SECTIONS.items()}
    session = {"session": SessionSettings}   # session.id: the nodes that refuse other sessions (docs/sessions.md)
    return {
        "recorder": {"recorder": RecorderSettings},
        "outcome_logger": {"": OutcomeLoggerSettings, **session},
        "valve_controller": {"valve": ValveConfig},
        "sim_evaluator": {**evaluator, **session},
        "optimizer": {"optimizer": OptimizerSettings, "quality_diversity": QualityDiversitySettings,
                      "selection": SelectionSettings, "profile": ProfileGrid, "printer": PrinterSpec,
                      "robot": ChassisSpec, "urdf_robot": UrdfRobotSpec, "stable_poses": ScreenSettings, **session},
        "rig": {"rig": RigSettings, "valve": ValveConfig, "speed_gate": SpeedGateConfig,
                "imu_outcome": ImuOutcomeConfig, **session},
        "campaign_runner": {"campaign": CampaignSpec, "runner": RunnerSettings, **session},
    }


def _declared_only(settings_cls, mapping):
    """``mapping`` without keys that are not fields of ``settings_cls`` (nested dataclasses likewise)."""
    if not isinstance(mapping, dict):
        return mapping
    hints = typing.get_type_hints(settings_cls)
    kept = {}
    for field in dataclasses.fields(settings_cls):
        if field.name in mapping:
            value = mapping[field.name]
            kept[field.name] = (_declared_only(hints[field.name], value)
                                if dataclasses.is_dataclass(hints[field.name]) else value)
    return kept


def _field_names(settings_cls, prefix):
    """``(fields, leaves)``: the dotted names of every field of ``settings_cls`` under ``prefix`` (nested dataclasses
    recursively) and of those whose values are not dataclasses (a leaf may hold a mapping, read whole)."""
    hints = typing.get_type_hints(settings_cls)
    fields, leaves = set(), set()
    for field in dataclasses.fields(settings_cls):
        name = f"{prefix}.{field.name}" if prefix else field.name
        fields.add(name)
        if dataclasses.is_dataclass(hints[field.name]):
            inner_fields, inner_leaves = _field_names(hints[field.name], name)
            fields |= inner_fields
            leaves |= inner_leaves
        else:
            leaves.add(name)
    return fields, leaves


@functools.lru_cache(maxsize=1)
def _known_names():
    """``(namespaces, fields, leaves)`` of every node's settings dataclasses (:func:`_field_names`), built once."""
    fields: typing.Set[str] = set()
    leaves: typing.Set[str] = set()
    namespaces = set()
    for node_sections in _node_sections().values():
        for prefix, settings_cls in node_sections.items():
            if not prefix:
                continue
            namespaces.add(prefix)
            node_fields, node_leaves = _field_names(settings_cls, prefix)
            fields |= node_fields
            leaves |= node_leaves
    return frozenset(namespaces), frozenset(fields), frozenset(leaves)


def unknown_parameters(flat: typing.Mapping[str, object]) -> typing.List[str]:
    """The dotted names in ``flat`` whose namespace one of the graph's settings dataclasses reads but which no field
    of any of them (in any node) matches, sorted; a name under a leaf field (a mapping value) is known."""
    namespaces, fields, leaves = _known_names()
    unknown = []
    for name in flat:
        if "." not in name or name.split(".", 1)[0] not in namespaces or name in fields:
            continue
        parts = name.split(".")
        if not any(".".join(parts[:i]) in leaves for i in range(1, len(parts))):
            unknown.append(name)
    return sorted(unknown)


def graph_namespaces(node_names: typing.Optional[typing.Iterable[str]] = None) -> typing.FrozenSet[str]:
    """The parameter namespaces the nodes ``node_names`` (default: every node a study starts; names of other nodes
    pass) apply: their settings' prefixes, ``bringup`` (the session's own) and, with the rig, ``launch_twin`` (its
    twin reads the parameter files ``rig.twin_config`` lists, the session's among them)."""
    sections = _node_sections()
    nodes = set(sections) if node_names is None else set(node_names)
    namespaces = {"bringup", *(prefix for node in nodes & set(sections) for prefix in sections[node] if prefix)}
    if "rig" in nodes:
        namespaces.add("launch_twin")
    return frozenset(namespaces)


@edge_parse
def check_graph_parameters(param_files: typing.Sequence[str], node_names: typing.Optional[typing.Sequence[str]] = None,
                           overrides: typing.Optional[dict] = None) -> typing.List[str]:
    """Return every problem in the parameters the nodes ``node_names`` (default: all a study starts) would read.

    Parameters
    ----------
    param_files : list of str
        Parameter files in load order (names of shipped files or paths), as the nodes get them.
    node_names : iterable of str, optional
        Which nodes to check.
    overrides : dict, optional
        ``{node name: {dotted parameter: value}}`` set on the node's command line (they win over the files).

    Returns
    -------
    list of str
        ``"<node>: <where>: <reason>"`` lines; empty when every value is valid.
    """
    sections = _node_sections()
    problems: typing.List[str] = []
    file_errors: typing.Set[str] = set()   # one file's error once, however many nodes read the file
    for node in node_names or sections:
        flat = load_parameters(list(param_files), node_name=node)
        flat.update((overrides or {}).get(node, {}))
        problems.extend(f"{node}: unknown parameter {name} (no node of the graph reads it)"
                        for name in unknown_parameters(flat))
        for prefix, settings_cls in sections[node].items():
            try:
                from_mapping(settings_cls, _declared_only(settings_cls, section(flat, prefix)), prefix or node)
            except (ConfigError, ValueError, TypeError) as exc:
                problems.append(f"{node}: {exc}")
        named: typing.List[typing.Tuple[str, str]] = []   # (what, error): files the node reads at start
        if node == "rig" and flat.get("rig.backend", "sim") == "sim":
            named += _twin_problems(flat)
        if node == "sim_evaluator":
            named += _objective_file_problems(flat)
        problems.extend(f"{node}: {what}: {error}" for what, error in named if error not in file_errors)
        file_errors.update(error for _what, error in named)
    return problems


@edge_parse
def _twin_problems(flat):
    """``[(what, error)]``: what the sim rig's twin would refuse in the files ``rig.twin_config`` names (it loads
    them at start)."""
    from rollability_ros.core.rig import RigSettings
    from rollability_ros.core.sim import launch_twin_settings_from_parameters

    twin_config = flat.get("rig.twin_config", RigSettings().twin_config)
    try:
        launch_twin_settings_from_parameters(load_parameters(list(twin_config)))
    except (ConfigError, ValueError, TypeError) as exc:
        return [(f"launch twin ({', '.join(map(str, twin_config))})", str(exc))]
    return []


@edge_parse
def _objective_file_problems(flat):
    """``[(what, error)]``: what the sim_evaluator would refuse in the files ``objective.twin_config`` and
    ``objective.campaign_config`` name (it reads them at start:
    :func:`~rollability_ros.core.sim.objectives.resolve_launch`); none when the ``objective`` section itself is
    refused (reported with the node's sections)."""
    from rollability_ros.core.sim import ObjectiveSettings, resolve_launch

    try:
        objective = from_mapping(ObjectiveSettings, _declared_only(ObjectiveSettings, section(flat, "objective")),
                                 "objective")
    except (ConfigError, ValueError, TypeError):
        return []
    try:
        resolve_launch(objective)
    except (ConfigError, ValueError, TypeError) as exc:
        return [(f"the objective's launch twin or campaign ({', '.join(map(str, objective.twin_config))}; "
                 f"{', '.join(map(str, objective.campaign_config))})", str(exc))]
    return []


@edge_parse
def refuse_bad_session(param_files: typing.Sequence[str], given_files: typing.Sequence[str],
                       nodes: typing.Mapping[str, dict], command: str) -> None:
    """Raise :class:`ConfigError` before a session starts ``nodes`` (``{node module: its overrides}``, from
    ``param_files``) when a parameter of the files the user gave (``given_files``) is one no node of it applies
    (:func:`graph_namespaces`), or any node would refuse its parameters (:func:`check_graph_parameters`)."""
    checked = [node for node in nodes if node in _node_sections()]
    check_given_files(given_files, graph_namespaces(checked), command)
    problems = check_graph_parameters(param_files, checked, {node: nodes[node] for node in checked})
    if len(problems) == 1:
        raise ConfigError(f"nothing started: {problems[0]}")
    if problems:
        raise ConfigError(f"nothing started: {len(problems)} invalid parameters:\n  " + "\n  ".join(problems))
