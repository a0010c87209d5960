"""Full ``ros2msg`` message definitions and RIHS01 type hashes, as rosbag2 stores them in MCAP schemas.

A bag must carry the complete definition of every recorded type so a reader without our package installed
can decode it. :func:`definition_for` builds the text the way rosbag2's MCAP storage plugin does: the root
type's ``.msg`` text, then every nested type once, depth-first in sorted order, each after a separator line of
80 ``=`` and a ``MSG: pkg/Type`` header. Interface files are looked up in this source checkout (package
``rollability_ros``: ``msg/``, ``srv/``, ``action/``) and in ``<prefix>/share/<pkg>/`` for every prefix on
``AMENT_PREFIX_PATH`` and ``sys.prefix`` (the ROS 2 PyPI wheels install ``share/`` into the virtualenv).
"""
import os
import re
import sys
import typing

#: ROS package name of this repository's own interfaces.
OWN_PACKAGE = "rollability_ros"

#: Separator between the root definition and each nested one (rosbag2 / mcap ``ros2msg`` convention).
SEPARATOR = "=" * 80

#: Primitive field types; everything else in a field line names a nested message type.
PRIMITIVE_TYPES = frozenset(
    "bool byte char float32 float64 int8 uint8 int16 uint16 int32 uint32 int64 uint64 string wstring".split()
)

#: A field or constant line of type ``char`` (or ``char[...]``).
_CHAR_FIELD = re.compile(r"(?m)^(\s*)char(?=[\s\[])")

#: Suffix of a service / action part type name -> (interface kind, index of the ``---`` section).
_PART_SECTIONS = {
    "srv": {"_Request": 0, "_Response": 1},
    "action": {"_Goal": 0, "_Result": 1, "_Feedback": 2},
}

#: Action feedback topic type: ``<Action>_FeedbackMessage`` wraps the feedback with the goal id.
_FEEDBACK_MESSAGE = "_FeedbackMessage"


def split_type_name(type_name: str) -> typing.Tuple[str, str, str]:
    """Split ``pkg/msg/Type``, ``pkg/srv/Type_Request`` or ``pkg/Type`` into ``(package, kind, name)``.

    Raises
    ------
    ValueError
        ``type_name`` is not of one of those forms.
    """
    parts = type_name.split("/") if isinstance(type_name, str) else []
    if len(parts) == 2:
        parts = [parts[0], "msg", parts[1]]
    if len(parts) != 3 or parts[1] not in ("msg", "srv", "action") or not all(parts):
        raise ValueError(f"message type name must look like 'pkg/msg/Type' or 'pkg/Type', got {type_name!r}")
    return parts[0], parts[1], parts[2]


def full_type_name(type_name: str) -> str:
    """Return the ``pkg/kind/Type`` form of ``type_name`` (``pkg/Type`` means ``pkg/msg/Type``)."""
    return "/".join(split_type_name(type_name))


def package_directories(package: str) -> typing.Iterator[str]:
    """Yield the directories that may hold ``package``'s ``msg/``, ``srv/`` and ``action/`` folders, in search order."""
    if package == OWN_PACKAGE:
        yield os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", ".."))
    prefixes = [p for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    for prefix in [*prefixes, sys.prefix]:
        yield os.path.join(prefix, "share", package)


def _read_interface_file(package, kind, name):
    """Return the text of ``<package>/<kind>/<name>.<kind>`` from the first directory that has it."""
    for directory in package_directories(package):
        path = os.path.join(directory, kind, f"{name}.{kind}")
        if os.path.isfile(path):
            with open(path, encoding="utf-8") as stream:
                return stream.read()
    searched = ", ".join(os.path.join(d, kind) for d in package_directories(package))
    raise ValueError(f"no definition for {package}/{kind}/{name}: {name}.{kind} not found in {searched}")


def _split_sections(text):
    """Split a ``.srv`` / ``.action`` text at its ``---`` lines."""
    sections: typing.List[typing.List[str]] = [[]]
    for line in text.splitlines(keepends=True):
        if line.strip() == "---":
            sections.append([])
        else:
            sections[-1].append(line)
    return ["".join(lines) for lines in sections]


def interface_text(type_name: str) -> str:
    """Return the definition text of one type alone (no nested types), as written in its interface file.

    Service and action parts (``pkg/srv/Foo_Request``, ``pkg/action/Foo_Goal``, ...) are cut out of the
    ``.srv`` / ``.action`` file; ``pkg/action/Foo_FeedbackMessage`` is the goal id plus the feedback, as rosidl
    generates it.
    """
    package, kind, name = split_type_name(type_name)
    if kind == "msg":
        return _read_interface_file(package, kind, name)
    if kind == "action" and name.endswith(_FEEDBACK_MESSAGE):
        action = name[: -len(_FEEDBACK_MESSAGE)]
        return f"unique_identifier_msgs/UUID goal_id\n{package}/action/{action}_Feedback feedback\n"
    for suffix, index in _PART_SECTIONS[kind].items():
        if name.endswith(suffix):
            sections = _split_sections(_read_interface_file(package, kind, name[: -len(suffix)]))
            if len(sections) != len(_PART_SECTIONS[kind]):
                raise ValueError(f"{package}/{kind}/{name[: -len(suffix)]}.{kind} does not have "
                                 f"{len(_PART_SECTIONS[kind])} sections separated by '---'")
            return _qualify_nested_types(sections[index], package)
    raise ValueError(f"{type_name!r}: a {kind} part name must end in one of {sorted(_PART_SECTIONS[kind])}")


def _field_type(line):
    """Return the field type of a ``.msg`` line without array / bound suffixes, or None for no field."""
    tokens = line.split("#", 1)[0].split()
    if len(tokens) < 2:
        return None
    return tokens[0].split("[", 1)[0].split("<=", 1)[0]


def _qualify_nested_types(text, package):
    """Prefix unqualified nested type names with ``package/``.

    A service or action part is not a ``msg/`` type, so readers would resolve its unqualified names in the
    wrong namespace; rosidl resolves them in the package's ``msg/``.
    """
    lines = []
    for line in text.splitlines(keepends=True):
        field_type = _field_type(line)
        if field_type and field_type not in PRIMITIVE_TYPES and "/" not in field_type:
            line = line.replace(field_type, f"{package}/{field_type}", 1)
        lines.append(line)
    return "".join(lines)


def nested_type_names(text: str, package: str) -> typing.List[str]:
    """Return the sorted set of nested type names that the field lines of ``text`` reference.

    Unqualified names are resolved in ``package``, as rosidl does; names keep the form they are written in
    (``pkg/Type``), which is the form rosbag2 writes into ``MSG:`` headers.
    """
    names = set()
    for line in text.splitlines():
        field_type = _field_type(line)
        if field_type and field_type not in PRIMITIVE_TYPES:
            names.add(field_type if "/" in field_type else f"{package}/{field_type}")
    return sorted(names)


def definition_for(type_name: str) -> str:
    """Return the full ``ros2msg`` definition of ``type_name`` with all nested types, as rosbag2 writes it.

    Parameters
    ----------
    type_name : str
        ``pkg/msg/Type`` (or ``pkg/Type``, ``pkg/srv/Foo_Request``, ``pkg/action/Foo_Goal`` ...).

    Raises
    ------
    ValueError
        The type name is malformed, or its interface file (or one of a nested type) is not found; the
        message names the type and the folders searched.
    """
    seen: typing.Set[str] = set()

    def append_recursive(name: str, depth: int) -> str:
        if depth > 50:
            raise ValueError(f"nested types of {type_name} are more than 50 levels deep (a cycle?)")
        text = interface_text(name)
        package = split_type_name(name)[0]
        for nested in nested_type_names(text, package):
            if nested not in seen:
                seen.add(nested)
                text += f"\n{SEPARATOR}\nMSG: {nested}\n" + append_recursive(nested, depth + 1)
        return text

    return append_recursive(type_name, 0)


def rihs01_hash(type_name: str, definition: str) -> str:
    """Return the ``RIHS01_<sha256>`` type description hash of ``type_name`` from its full ``ros2msg`` definition.

    Computed by rosbags' implementation of REP-2011 over the type description that the definition
    describes (constants, comments and default values do not enter the hash, as in rosidl). rosidl maps
    the ``.msg`` type ``char`` to ``uint8`` before hashing, so it is mapped here too (rosbags alone does not).
    """
    from rosbags.typesys import Stores, get_typestore, get_types_from_msg

    package, kind, short_name = split_type_name(type_name)
    name = f"{package}/{kind}/{short_name}"
    # rosbags' parser files every root type under msg/; parse it there and register it under its real name
    parsed_name = f"{package}/msg/{short_name}"
    typestore = get_typestore(Stores.EMPTY)
    as_rosidl_hashes_it = _CHAR_FIELD.sub(r"\1uint8", definition)
    try:
        types = get_types_from_msg(as_rosidl_hashes_it, parsed_name)
        types[name] = types.pop(parsed_name)
        typestore.register(types)
    except Exception as exc:  # rosbags raises its own parser errors; report them as bad input
        raise ValueError(f"the definition of {name} does not parse as ros2msg: {exc}") from exc
    return typestore.hash_rihs01(name)
