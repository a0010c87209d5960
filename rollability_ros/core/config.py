"""ROS 2 parameter files (``config/*.yaml``) read by both the nodes and the CLI.

A parameter file maps node names (``/**`` for every node, or ``optimizer``, ``/ns/rig``, ...) to
``ros__parameters``. Nested mappings are ROS parameter namespaces: ``sim: {time_step_s: ...}`` is the parameter
``sim.time_step_s``. :func:`load_parameters` merges one or more files into one flat ``{dotted name: value}``
dict for a node; :func:`section` cuts a namespace back out as a nested dict for a core dataclass, and
:func:`settings_from_sections` parses a whole flat dict once, at the edge (CLI or node), into a dataclass of typed
sections that the core is then handed.
"""
import dataclasses
import math
import os
import re
import typing

import yaml

from rollability_ros.core import safe_yaml

#: The folder of the config files shipped with the package (source checkout or install share dir).
CONFIG_ENV = "ROLLABILITY_CONFIG_DIR"


#: Every parameter namespace the project reads (the first part of a dotted name), and ROS's own. A dotted parameter
#: outside them is a misspelt namespace (``physics.time_step_s`` for ``sim.time_step_s``): without this check it
#: would be ignored and its section would silently keep its defaults. test_config keeps this list true to the
#: shipped files, the graph's preflight sections and the nodes' declared prefixes.
KNOWN_NAMESPACES = frozenset({
    "bringup", "calibration", "campaign", "designs", "evaluator", "imu_outcome", "launch_twin", "objective",
    "optimizer", "player", "printer", "profile", "quality_diversity", "recorder", "rig", "robot", "runner",
    "selection", "session", "sim", "speed_gate", "stable_poses", "tip_monitor", "trial", "urdf_robot", "valve",
    "qos_overrides"})


class ConfigError(ValueError):
    """A parameter file or a parameter value is unusable; the message names the file and the parameter."""


@dataclasses.dataclass
class SessionSettings:
    """``session.*``: the session (``rollability study`` / ``bringup``) a node belongs to; nodes of a session talk only
    to nodes of the same one (docs/sessions.md)."""

    id: str = dataclasses.field(default="", metadata={
        "description": "the session this node belongs to (session.yaml's id): goals, results and records of another "
                       "session are refused and logged once; \"\" = a node outside any session, which accepts all"})

    def refusal(self, other: str, what: str) -> str:
        """"" when ``what`` (a goal, a result) of session ``other`` may be served or used here, else the reason: a
        node of a session takes only its own session's; one outside any session takes all."""
        if not self.id or other == self.id:
            return ""
        return f"{what} of session {other or '(none)'} refused: this node belongs to session {self.id}"


#: A run, study or session id: one path component of letters, digits, '.', '_' and '-' (not starting with '.' or
#: '-'), since it names a folder under the output directory and a key in the stores.
_PATH_COMPONENT = re.compile(r"[A-Za-z0-9_][A-Za-z0-9._-]{0,127}")


def check_path_component(value: object, what: str) -> str:
    """Return ``value`` if it is a safe single path component (:data:`_PATH_COMPONENT`), else raise ConfigError
    naming ``what``: an id like ``../escaped`` or ``''`` would write outside the output folder or into it."""
    if not isinstance(value, str) or not _PATH_COMPONENT.fullmatch(value):
        raise ConfigError(f"{what} must be one folder name of letters, digits, '.', '_' and '-' (at most 128, not "
                          f"starting with '.' or '-'), got {value!r}")
    return value


def check_output_dir(path: str, what: str, keeps: typing.Iterable[str] = ()) -> None:
    """Raise ConfigError unless ``path`` can receive a command's results: missing, an empty folder, or (with
    ``keeps``, names of files a command writes) a folder holding none of them, so an earlier result is never
    overwritten and a file never replaced by a folder; ``what`` names the flag in the message."""
    if os.path.lexists(path) and not os.path.isdir(path):
        raise ConfigError(f"{what} {path} is an existing file, not a folder; choose another {what}")
    held = sorted(name for name in keeps if os.path.lexists(os.path.join(path, name)))
    if held:
        raise ConfigError(f"{what} {path} already holds the results of an earlier run ({', '.join(held)}); choose "
                          f"a new folder for {what}")


def check_parent_steps(path: str, what: str) -> str:
    """Return ``path`` unless its ``..`` steps climb above the filesystem root (from the working directory for a
    relative path), else raise ConfigError naming ``what``: the operating system silently stops at ``/`` (the path
    means somewhere else than its author counted) and SQLite refuses such a path outright."""
    absolute = path if os.path.isabs(path) else os.path.join(os.getcwd(), path)
    depth = 0
    for part in absolute.split(os.sep):
        if part == "..":
            if depth == 0:
                raise ConfigError(f"{what} {path!r} has more '..' than {os.getcwd() if absolute != path else '/'} "
                                  f"has levels (it climbs above /); give a path that stays inside the file system")
            depth -= 1
        elif part not in ("", "."):
            depth += 1
    return path


def config_dir() -> str:
    """Return the directory holding the shipped ``config/*.yaml`` files.

    Looks at ``$ROLLABILITY_CONFIG_DIR``, then the source checkout (``<repo>/config``), then the ament share
    directory of an installed package (``<prefix>/share/rollability_ros/config``).
    """
    candidates = []
    if os.environ.get(CONFIG_ENV):
        candidates.append(os.environ[CONFIG_ENV])
    here = os.path.dirname(os.path.abspath(__file__))
    candidates.append(os.path.normpath(os.path.join(here, "..", "..", "config")))
    # installed: <prefix>/lib/pythonX.Y/site-packages/rollability_ros/core -> <prefix>/share/rollability_ros/config
    candidates.append(os.path.normpath(os.path.join(here, *[".."] * 5, "share", "rollability_ros", "config")))
    for path in candidates:
        if os.path.isdir(path):
            return path
    raise ConfigError(f"no config directory found (looked in {', '.join(candidates)}); set {CONFIG_ENV}")


def resolve_config_path(name_or_path: str) -> str:
    """Return a path for ``name_or_path``: an existing file as given, else ``<config_dir>/<name>[.yaml]``."""
    if os.path.isfile(name_or_path):
        return name_or_path
    base = config_dir()
    for candidate in (os.path.join(base, name_or_path), os.path.join(base, name_or_path + ".yaml")):
        if os.path.isfile(candidate):
            return candidate
    raise ConfigError(f"config file not found: {name_or_path} (also looked in {base})")


def _flatten(mapping, prefix, out, path):
    for key, value in mapping.items():
        if not isinstance(key, str) or not key:
            raise ConfigError(f"{path}: parameter names must be non-empty strings, got {key!r} under '{prefix}'")
        name = f"{prefix}.{key}" if prefix else key
        if isinstance(value, dict):
            _flatten(value, name, out, path)
        else:
            out[name] = value


def read_parameter_file(path: str) -> typing.Dict[str, typing.Dict[str, object]]:
    """Read a ROS 2 parameter file into ``{node name: {dotted parameter: value}}``.

    Raises :class:`ConfigError` naming the file for unreadable YAML, YAML beyond the limits of
    :mod:`~rollability_ros.core.safe_yaml` (too deep, aliases expanding too far, a key written twice) or a layout
    that is not ``<node>: {ros__parameters: {...}}``.
    """
    try:
        with open(path, encoding="utf-8") as stream:
            document = safe_yaml.load(stream)
    except OSError as exc:
        raise ConfigError(f"cannot read parameter file {path}: {exc.strerror}") from exc
    except UnicodeDecodeError as exc:
        raise ConfigError(f"parameter file {path} is not UTF-8 text ({exc.reason} at byte {exc.start})") from exc
    except safe_yaml.YamlLimitError as exc:
        raise ConfigError(f"parameter file {path}: {exc}") from exc
    except yaml.YAMLError as exc:
        raise ConfigError(f"parameter file {path} is not valid YAML: {safe_yaml.one_line(exc)}") from exc
    if document is None:
        return {}
    if not isinstance(document, dict):
        raise ConfigError(f"parameter file {path}: top level must map node names to ros__parameters")
    nodes = {}
    for node_name, body in document.items():
        if not isinstance(body, dict) or "ros__parameters" not in body:
            raise ConfigError(f"parameter file {path}: '{node_name}' has no 'ros__parameters' mapping")
        params = body["ros__parameters"] or {}
        if not isinstance(params, dict):
            raise ConfigError(f"parameter file {path}: '{node_name}.ros__parameters' must be a mapping")
        flat: typing.Dict[str, object] = {}
        _flatten(params, "", flat, path)
        nodes[str(node_name)] = flat
    return nodes


def _node_matches(pattern, node_name):
    if pattern in ("/**", "**"):
        return True
    return pattern.lstrip("/") == node_name.lstrip("/") or pattern.lstrip("/").split("/")[-1] == node_name.lstrip("/").split("/")[-1]


def load_parameters(paths: typing.Union[str, os.PathLike, typing.Iterable[typing.Union[str, os.PathLike]]],
                    node_name: str = "/**") -> typing.Dict[str, object]:
    """Merge parameter files into one flat dict for ``node_name``.

    Later files override earlier ones; within a file, a section naming the node overrides ``/**``.
    ``paths`` is one path or a list; each may be a bare name of a shipped file (``"sim"``).
    """
    if isinstance(paths, (str, os.PathLike)):
        paths = [paths]
    merged: typing.Dict[str, object] = {}
    for path in paths:
        resolved = resolve_config_path(os.fspath(path))
        nodes = read_parameter_file(resolved)
        for pattern in sorted(nodes, key=lambda p: p not in ("/**", "**")):  # wildcard first, then specific
            if node_name in ("/**", "**") or _node_matches(pattern, node_name):
                check_namespaces(nodes[pattern], f"parameter file {resolved}")
                merged.update(nodes[pattern])
    return merged


def check_namespaces(flat: typing.Iterable[str], where: str) -> None:
    """Raise :class:`ConfigError` naming ``where`` and the parameter for a dotted name in ``flat`` whose namespace
    is not one of :data:`KNOWN_NAMESPACES` (names without a dot, e.g. ``use_sim_time``, pass)."""
    for name in flat:
        namespace = name.split(".", 1)[0]
        if "." in name and namespace not in KNOWN_NAMESPACES:
            raise ConfigError(f"{where}: unknown parameter namespace {namespace!r} (parameter {name}); known: "
                              f"{', '.join(sorted(KNOWN_NAMESPACES))}")


#: Namespaces every command passes on untouched: ROS's own (the QoS a node's publishers and subscribers take).
PASS_THROUGH_NAMESPACES = frozenset({"qos_overrides"})


def check_given_files(paths: typing.Iterable[typing.Union[str, os.PathLike]], reads: typing.Iterable[str],
                      command: str,
                      unread: typing.Optional[typing.Callable[[str, typing.Mapping[str, object]], bool]] = None
                      ) -> typing.List[typing.Tuple[str, str]]:
    """Raise :class:`ConfigError` naming the file, the parameter and ``command`` for the first dotted parameter of
    the files ``paths`` (those a user gave the command, e.g. with ``--config``) whose namespace is not in ``reads``,
    the namespaces ``command`` applies: it would be dropped without a word (``launch_twin.foam.length_m`` given to
    an evaluation that launches no twin). Inside a namespace it reads, :func:`from_mapping` refuses unknown names.

    ``unread(name, file's flat parameters)`` may take such a name that changes nothing ``command`` computes (a
    print file's robust draws given to calibrate); the ``(file, name)`` pairs it took are returned, for the command
    to say so and leave them out of what it loads."""
    reads = frozenset(reads) | PASS_THROUGH_NAMESPACES
    taken: typing.List[typing.Tuple[str, str]] = []
    for path in paths:
        resolved = resolve_config_path(os.fspath(path))
        given = load_parameters([resolved])
        for name in given:
            if "." in name and name.split(".", 1)[0] not in reads:
                if unread is not None and unread(name, given):
                    taken.append((resolved, name))
                    continue
                raise ConfigError(f"parameter file {resolved}: {command} does not read {name} (it reads "
                                  f"{', '.join(sorted(reads - PASS_THROUGH_NAMESPACES))}); remove it or give the "
                                  f"file to a command that reads it")
    return taken


def section(flat: typing.Mapping[str, object], prefix: str) -> typing.Dict[str, object]:
    """Return the parameters under ``prefix.`` as a nested dict (``section(p, "sim")["time_step_s"]``)."""
    out: typing.Dict[str, object] = {}
    lead = prefix + "." if prefix else ""
    for name, value in flat.items():
        if not name.startswith(lead):
            continue
        parts = name[len(lead):].split(".")
        node = out
        for part in parts[:-1]:
            child = node.setdefault(part, {})
            if not isinstance(child, dict):
                raise ConfigError(f"parameter {name}: {'.'.join(parts[:parts.index(part) + 1])} is both a value and "
                                  "a namespace")
            node = child
        node[parts[-1]] = value
    return out


#: A ROS 2 parameter file's document: ``{node name: {"ros__parameters": {namespace: {...}, name: value}}}``.
ParameterDocument = typing.Dict[str, typing.Dict[str, typing.Dict[str, object]]]


def as_list(value: object) -> typing.List[object]:
    """A parameter's value as a list: a list's or tuple's items, else the one value."""
    return list(value) if isinstance(value, (list, tuple)) else [value]


def integer_parameter(parameters: typing.Mapping[str, object], name: str, default: int) -> int:
    """The integer parameter ``name`` of flat ``parameters`` (``default`` when absent); :class:`ConfigError` in
    one line naming it when it is not an integer."""
    value = parameters.get(name, default)
    if isinstance(value, bool) or not isinstance(value, int):
        raise ConfigError(wrong_type(name, int, value))
    return value


def parameter_document(flat: typing.Mapping[str, object]) -> ParameterDocument:
    """Flat ``{dotted name: value}`` parameters as a ROS 2 parameter file's document for every node:
    ``{"/**": {"ros__parameters": {...nested by namespace...}}}`` (tuples written as lists); the inverse of
    :func:`read_parameter_file` for one ``/**`` section."""
    values = {name: list(value) if isinstance(value, tuple) else value for name, value in flat.items()}
    return {"/**": {"ros__parameters": section(values, "")}}


#: A settings dataclass built by :func:`from_mapping`.
_Settings = typing.TypeVar("_Settings")

#: A settings field's ``metadata`` (``dataclasses.field(metadata=...)``): its declared ``"range"`` ``(low, high)``,
#: ``"exclusive"`` (``"low"``, ``"high"`` or ``"both"``), and any other keys the field documents.
FieldMetadata = typing.Mapping[str, object]


def declared_range(metadata: FieldMetadata) -> typing.Tuple[float, float]:
    """The ``(low, high)`` a settings field declares in ``metadata["range"]``; ``TypeError`` naming the value when it
    is not a pair of numbers (a mistake in the field's declaration, not in the user's input)."""
    value = metadata["range"]
    if (isinstance(value, (tuple, list)) and len(value) == 2
            and all(isinstance(end, (int, float)) and not isinstance(end, bool) for end in value)):
        return value[0], value[1]
    raise TypeError(f"a settings field's range must be (low, high) numbers, got {value!r}")


def interval(metadata: FieldMetadata) -> str:
    """The declared range of a settings field in interval notation: ``[0.0, 100.0]``, or ``(0.0, 100.0]`` when
    ``metadata["exclusive"]`` (``"low"``, ``"high"`` or ``"both"``) leaves an end out ("must be > 0")."""
    low, high = declared_range(metadata)
    exclusive = metadata.get("exclusive", "")
    return (f"{'(' if exclusive in ('low', 'both') else '['}{low}, {high}"
            f"{')' if exclusive in ('high', 'both') else ']'}")


def in_range(value: float, metadata: FieldMetadata) -> bool:
    """True when the number ``value`` lies in the field's declared range (:func:`interval`); NaN never does."""
    low, high = declared_range(metadata)
    exclusive = metadata.get("exclusive", "")
    above = value > low if exclusive in ("low", "both") else value >= low
    below = value < high if exclusive in ("high", "both") else value <= high
    return above and below


def out_of_range(name: str, value: object, metadata: FieldMetadata) -> str:
    """The one line that refuses ``value`` for the setting ``name`` (a dotted parameter name), from the CLI and
    from a node alike: ``optimizer.popsize out of range: 1 is not in [2, 100000]``."""
    return f"{name} out of range: {value} is not in {interval(metadata)}"


#: What a value of each scalar field type is called in a refusal.
_KINDS = {float: "a number", int: "an integer", bool: "true or false", str: "text"}


def wrong_type(name: str, field_type: type, value: object,
               metadata: typing.Optional[FieldMetadata] = None) -> str:
    """The one line that refuses ``value`` of the wrong type for setting ``name`` (CLI and node alike):
    ``optimizer.popsize: expected an integer in [2, 100000], got 'twelve'``."""
    return f"{name}: expected {_KINDS.get(field_type, field_type.__name__)}{_in(metadata)}, got {value!r}"


def _check_value(value, field_type, where, metadata=None):
    """Coerce and check one value against a dataclass field type (float, int, bool, str, lists, tuples) and, for a
    number, against the field's declared ``metadata["range"]``."""
    value_range = (metadata or {}).get("range")
    origin = typing.get_origin(field_type)
    if field_type is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(wrong_type(where, float, value, metadata))
        value = float(value)
        if value_range is None and not math.isfinite(value):
            raise ConfigError(f"{where}: must be finite, got {value!r}")
    elif field_type is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(wrong_type(where, int, value, metadata))
    elif field_type is bool:
        if not isinstance(value, bool):
            raise ConfigError(wrong_type(where, bool, value))
    elif field_type is str:
        if not isinstance(value, str):
            raise ConfigError(wrong_type(where, str, value))
    elif origin in (list, tuple):
        if not isinstance(value, (list, tuple)):
            raise ConfigError(f"{where}: expected a list, got {value!r}")
        args = typing.get_args(field_type)
        item_type = args[0] if args else typing.Any
        items = [_check_value(v, item_type, f"{where}[{i}]") for i, v in enumerate(value)]
        return tuple(items) if origin is tuple else items
    if value_range is not None and field_type in (int, float) and not in_range(value, metadata):
        raise ConfigError(out_of_range(where, value, metadata))
    return value


def _in(metadata):
    """`` in [low, high]`` for a field that declares its range, else ""."""
    return f" in {interval(metadata)}" if metadata and "range" in metadata else ""


def check_settings(settings: object, where: str) -> None:
    """Check a built settings dataclass: every numeric field (nested settings too) against its declared
    ``metadata["range"]``, then its ``validate()``, the rules that span fields. Raises :class:`ConfigError` naming
    ``where.field``; the one check every builder (:func:`from_mapping`, the nodes, the core's entry points) runs."""
    hints = typing.get_type_hints(type(settings))
    for field in dataclasses.fields(typing.cast(typing.Any, settings)):
        value = getattr(settings, field.name)
        name = f"{where}.{field.name}" if where else field.name
        if dataclasses.is_dataclass(value) and not isinstance(value, type):
            check_settings(value, name)
        elif "range" in field.metadata and hints[field.name] in (int, float):
            _check_value(value, hints[field.name], name, field.metadata)
    validate = getattr(settings, "validate", None)
    if callable(validate):
        try:
            validate()
        except ConfigError:
            raise
        except ValueError as exc:
            raise ConfigError(f"{where}: {exc}" if where else str(exc)) from exc


def from_mapping(cls: typing.Type[_Settings], mapping: object,
                 where: str) -> _Settings:
    """Build dataclass ``cls`` from a (nested) mapping, checking names and types.

    ``mapping`` is what a parameter file held there: a dict, or None (all defaults); anything else is refused.
    Unknown keys and wrongly typed values raise :class:`ConfigError` naming ``where.key``; missing keys take
    the dataclass defaults. Nested dataclass fields are built recursively. A number outside its field's declared
    ``metadata["range"]`` (NaN included) is refused in one line (:func:`out_of_range`); after construction
    :func:`check_settings` runs the dataclass's ``validate()`` (the rules that span fields).
    """
    if mapping is None:
        mapping = {}
    if not isinstance(mapping, dict):
        raise ConfigError(f"{where}: expected a mapping, got {mapping!r}")
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(typing.cast(typing.Any, cls))}   # refuses a non-dataclass
    unknown = sorted(set(mapping) - set(fields))
    if unknown:
        raise ConfigError(f"{where}: unknown parameter(s) {', '.join(unknown)}; known: {', '.join(sorted(fields))}")
    kwargs = {}
    for name, value in mapping.items():
        field_type = hints[name]
        if isinstance(field_type, type) and dataclasses.is_dataclass(field_type):
            kwargs[name] = from_mapping(field_type, value, f"{where}.{name}")
        else:
            kwargs[name] = _check_value(value, field_type, f"{where}.{name}", fields[name].metadata)
    obj = cls(**kwargs)
    check_settings(obj, where)
    return obj


def settings_from_sections(cls: typing.Type[_Settings], flat: typing.Mapping[str, object],
                           namespaces: typing.Optional[typing.Mapping[str, str]] = None,
                           optional: typing.Iterable[str] = ()) -> _Settings:
    """Parse flat ``{dotted name: value}`` parameters once into ``cls``, a dataclass whose fields are settings
    dataclasses, each built (:func:`from_mapping`) from the parameters under its namespace: ``namespaces`` maps a
    field to it (default: the field's name). A field named in ``optional`` is None when ``flat`` holds none of its
    namespace. A field whose metadata names what it is ``resolved_from`` (settings the edge reads from files the
    sections name, e.g. the launch twin of ``objective.twin_config``) is no namespace: it keeps its default here.
    Errors name the namespace and parameter (``optimizer: popsize must be >= 2, got 1``)."""
    hints = typing.get_type_hints(cls)
    kwargs: typing.Dict[str, typing.Any] = {}
    for field in dataclasses.fields(typing.cast(typing.Any, cls)):
        if "resolved_from" in field.metadata:
            continue
        namespace = (namespaces or {}).get(field.name, field.name)
        values = section(flat, namespace)
        if field.name in optional and not values:
            kwargs[field.name] = None
            continue
        field_type = hints[field.name]
        args = [arg for arg in typing.get_args(field_type) if arg is not type(None)]
        kwargs[field.name] = from_mapping(args[0] if field.name in optional else field_type, values, namespace)
    return cls(**kwargs)


#: A function declared by :func:`edge_parse` or :func:`file_schema` (returned unchanged).
_Function = typing.TypeVar("_Function", bound=typing.Callable[..., object])


def edge_parse(function: _Function) -> _Function:
    """Declare ``function`` the parse of one kind of settings from flat parameters or parameter files (built on
    :func:`section`, :func:`from_mapping`, :func:`settings_from_sections`): defined next to its dataclasses, called
    once by an edge (a node or the CLI, or another edge parse it is made of) that then hands the core the typed
    settings. The core never calls it; ``test/core/test_settings_edges.py`` checks both statically. Returns
    ``function`` unchanged."""
    return function


def file_schema(kind: str) -> typing.Callable[[_Function], _Function]:
    """Declare the decorated function the one reader of a kind of file that records its own settings (``kind``,
    e.g. ``"designs file"``: the selection writes the profile grid its designs were made on next to their heights),
    the file's schema reader: the core reads such a file wherever it needs its contents, always through this
    function. It is not a parameter-file parse: one reader per kind, and it calls no :func:`edge_parse`
    (``test/core/test_settings_edges.py`` checks both statically). Returns the function unchanged."""
    def declare(function: _Function) -> _Function:
        return function
    return declare


def with_values(settings: _Settings, namespaces: typing.Mapping[str, str],
                values: typing.Mapping[str, object]) -> _Settings:
    """Typed ``settings`` (a dataclass whose fields are settings dataclasses, each read from the namespace
    ``namespaces`` maps it to, as :func:`settings_from_sections` builds them) with the parameters ``values``
    (``{dotted parameter name: value}``, e.g. ``{"launch_twin.foam.restitution": 0.4}``) set: no parse, a copy with
    those fields replaced, each value checked as :func:`from_mapping` checks a file's (the same one-line
    :class:`ConfigError` naming the parameter), then every changed section's :func:`check_settings`."""
    fields = {namespace: name for name, namespace in namespaces.items()}
    changed: typing.Dict[str, object] = {}
    for dotted, value in values.items():
        namespace, _, rest = dotted.partition(".")
        if namespace not in fields or not rest:
            raise ConfigError(f"{dotted}: not a parameter of the namespaces {', '.join(sorted(fields))}")
        name = fields[namespace]
        changed[name] = _with_value(changed.get(name, getattr(settings, name)), rest.split("."), value, namespace)
    for name, section_settings in changed.items():
        check_settings(section_settings, namespaces[name])
    return dataclasses.replace(typing.cast(typing.Any, settings), **changed)


def _with_value(settings, path, value, where):
    """Dataclass ``settings`` (read from the namespace ``where``) with the field at ``path`` (names) set to
    ``value``, checked like a file's value."""
    hints = typing.get_type_hints(type(settings))
    fields = {f.name: f for f in dataclasses.fields(settings)}
    name, name_where = path[0], f"{where}.{path[0]}"
    if name not in fields:
        raise ConfigError(f"{where}: unknown parameter(s) {name}; known: {', '.join(sorted(fields))}")
    field_type = hints[name]
    if isinstance(field_type, type) and dataclasses.is_dataclass(field_type):
        if len(path) == 1:
            raise ConfigError(f"{name_where}: expected a mapping, got {value!r}")
        return dataclasses.replace(settings, **{name: _with_value(getattr(settings, name), path[1:], value,
                                                                  name_where)})
    if len(path) > 1:
        raise ConfigError(f"parameter {where}.{'.'.join(path)}: {name_where} is both a value and a namespace")
    return dataclasses.replace(settings, **{name: _check_value(value, field_type, name_where, fields[name].metadata)})


def value_of(settings: object, namespaces: typing.Mapping[str, str], dotted: str) -> object:
    """The value of the parameter ``dotted`` (``launch_twin.foam.restitution``) in typed ``settings`` (a dataclass
    of settings sections, ``namespaces`` as for :func:`with_values`); :class:`ConfigError` naming a name that is no
    value of them."""
    fields = {namespace: name for name, namespace in namespaces.items()}
    namespace, _, rest = dotted.partition(".")
    if namespace not in fields or not rest:
        raise ConfigError(f"{dotted}: not a parameter of the namespaces {', '.join(sorted(fields))}")
    value = getattr(settings, fields[namespace])
    for part in rest.split("."):
        if not (dataclasses.is_dataclass(value) and part in {f.name for f in dataclasses.fields(value)}):
            raise ConfigError(f"{dotted}: not a parameter of the namespaces {', '.join(sorted(fields))}")
        value = getattr(value, part)
    if dataclasses.is_dataclass(value):
        raise ConfigError(f"parameter {dotted}: is a namespace, not a value")
    return value
