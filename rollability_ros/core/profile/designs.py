"""Configuration ids of the launch campaign -> profile solids: the baseline, selected designs, STL/OBJ files.

A configuration id (``LaunchCondition.configuration``) names the profile mounted on the chassis:

``baseline``
    no profile (the bare chassis).
a label of ``designs_file``
    a ``designs.yaml`` written by ``rollability select`` (:func:`rollability_ros.core.optimization.design_set.designs_document`:
    namespace ``designs`` with ``labels``, the design ``grid`` and ``<label>.heights``); the solid is rebuilt from
    the heights on that grid (:func:`rollability_ros.core.profile.geometry.profile_mesh`), exactly as it was evaluated.
a label of ``mesh_labels``
    the STL/OBJ file at the same index of ``mesh_files`` (metres, profile frame, base on z = 0), e.g. a design
    edited in CAD (:func:`rollability_ros.core.profile.geometry.load_profile_mesh`). A pair of empty strings stands for
    "no files" (a ROS 2 parameter file cannot hold an empty list).

A label defined twice, or the id ``baseline`` used as a label, is refused. Relative paths are taken from the
current working directory. Solids are cached per file version (path, size, modification time), so a campaign
reads each file once and a rewritten file is read again.
"""
import dataclasses
import functools
import math
import os
import typing

from rollability_ros.core.profile import geometry
from rollability_ros.core.config import ConfigError, file_schema, from_mapping, load_parameters, section

#: The configuration id of the bare chassis.
BASELINE = "baseline"


@dataclasses.dataclass
class DesignSources:
    """Where the profiles of the configuration ids come from (``config/launch_twin.yaml``, ``launch_twin.designs``)."""

    designs_file: str = ""
    mesh_labels: typing.List[str] = dataclasses.field(default_factory=list)
    mesh_files: typing.List[str] = dataclasses.field(default_factory=list)

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first unusable field."""
        if len(self.mesh_labels) != len(self.mesh_files):
            raise ValueError(f"mesh_labels ({len(self.mesh_labels)}) and mesh_files ({len(self.mesh_files)}) "
                             "must have the same length")
        if any(bool(label) != bool(path) for label, path in zip(self.mesh_labels, self.mesh_files)):
            raise ValueError("every mesh_labels entry needs a mesh_files entry and the other way round")
        labels = [label for label in self.mesh_labels if label]
        if BASELINE in labels:
            raise ValueError(f"'{BASELINE}' is the bare chassis and cannot name a mesh file")
        repeated = sorted({label for label in labels if labels.count(label) > 1})
        if repeated:
            raise ValueError(f"mesh_labels repeats {', '.join(repeated)}")

    def meshes(self) -> typing.Dict[str, str]:
        """``{label: mesh file}``; a pair of empty strings is a placeholder (a ROS 2 parameter list cannot be
        empty) and is skipped."""
        return {label: path for label, path in zip(self.mesh_labels, self.mesh_files) if label}


def _file_version(path):
    """``(path, size, mtime_ns)`` of an existing file; ``FileNotFoundError`` naming it otherwise."""
    if not os.path.isfile(path):
        raise FileNotFoundError(f"profile source file not found: {path}")
    stat = os.stat(path)
    return os.path.abspath(path), stat.st_size, stat.st_mtime_ns


#: The ``designs.grid`` keys every designs file carries (``rollability select`` writes them all): the grid the
#: heights were chosen on. A missing one would take the default grid's value and rebuild another solid.
DESIGN_GRID_KEYS = ("rows", "cols", "length_m", "width_m", "height_min", "height_max", "unit_m")


def _design_grid(designs: typing.Mapping[str, object], path: str) -> object:
    """The file's ``designs.grid``; :class:`ConfigError` naming the file when it or one of :data:`DESIGN_GRID_KEYS`
    is missing (a wrongly typed value is :func:`from_mapping`'s to refuse)."""
    if "grid" not in designs:
        raise ConfigError(f"{path}: designs.grid is missing: the heights mean nothing without the grid they were "
                          f"chosen on ({', '.join(DESIGN_GRID_KEYS)}; rollability select writes it)")
    grid = designs["grid"]
    missing = [key for key in DESIGN_GRID_KEYS if isinstance(grid, dict) and key not in grid]
    if missing:
        raise ConfigError(f"{path}: designs.grid has no {', '.join(missing)}: the heights mean nothing without the "
                          "grid they were chosen on (rollability select writes all of "
                          f"{', '.join(DESIGN_GRID_KEYS)})")
    return grid


@file_schema("designs file")
@functools.lru_cache(maxsize=16)
def _read_designs(version):
    """``(grid, {label: heights}, print or None)`` of the designs file ``version`` (see :func:`_file_version`);
    the print is the file's ``designs.print`` (:func:`check_printed_with`)."""
    path = version[0]
    designs = section(load_parameters([path]), "designs")
    labels = designs.get("labels")
    if not isinstance(labels, list) or not all(isinstance(label, str) and label for label in labels):
        raise ConfigError(f"{path}: designs.labels must be a list of labels")
    if BASELINE in labels:
        raise ConfigError(f"{path}: '{BASELINE}' cannot label a design")
    twice = sorted({label for label in labels if labels.count(label) > 1})
    if twice:
        raise ConfigError(f"{path}: design {twice[0]} is listed twice in designs.labels")
    grid = from_mapping(geometry.ProfileGrid, _design_grid(designs, path), f"{path}: designs.grid")
    heights = {}
    for label in labels:
        entry = designs.get(label)
        if not isinstance(entry, dict) or "heights" not in entry:
            raise ConfigError(f"{path}: design {label} has no designs.{label}.heights")
        values = entry["heights"]   # YAML reads true as 1 and a lone number as no list: neither is a design's heights
        if not isinstance(values, list) or not all(isinstance(h, (int, float)) and not isinstance(h, bool)
                                                   for h in values):
            raise ConfigError(f"{path}: designs.{label}.heights must be a list of numbers (simulation units), got "
                              f"{values!r:.80}")
        heights[label] = tuple(values)
    printed = designs.get("print")
    if printed is not None and not isinstance(printed, dict):
        raise ConfigError(f"{path}: designs.print must be a mapping of the print's settings")
    return grid, heights, printed


@functools.lru_cache(maxsize=16)
def _designs_mesh(version, label):
    grid, heights, _ = _read_designs(version)
    try:
        return geometry.profile_mesh(heights[label], grid)
    except ValueError as exc:
        raise ConfigError(f"{version[0]}: design {label}: {exc}") from exc


@functools.lru_cache(maxsize=16)
def _file_mesh(version):
    return geometry.load_profile_mesh(version[0])


def designs_file_labels(path: str) -> typing.List[str]:
    """The design labels of the designs file ``path``, in its order (read by its one reader); ``ConfigError`` for a
    bad file, ``FileNotFoundError`` for a missing one."""
    return list(_read_designs(_file_version(path))[1])


def check_printed_with(path: str, instructions: typing.Mapping[str, typing.Union[str, float]],
                       option: str = "--config") -> None:
    """Refuse to launch the designs of ``path`` under another print than the one it tells the lab to use.

    A designs file states how its designs are printed (``designs.print``: the robot's ``profile_print`` and
    ``profile_mass_scale`` when they were chosen; :mod:`~rollability_ros.core.optimization.design_set`), and a
    design's mass, so its launches, follow from that print. ``instructions`` is the print of the robot in use
    (``print_instructions()``). Raises :class:`ConfigError` naming each setting that differs and the parameter
    file to give; nothing for a file that states no print (written before it was recorded). The mass multiplier
    (``profile_mass_scale``) is not compared: it is the print model's error on the rig (measured / modelled, what
    calibration fits), not an instruction to the lab. ``option`` is the command's flag that takes a parameter file."""
    stated = _read_designs(_file_version(path))[2]
    if stated is None:
        return
    differ = print_differences(stated, instructions, ("designs", "loaded"), ignore={"profile_mass_scale"})
    if differ:
        raise ConfigError(f"{path}: its designs were chosen for another print than the robot loaded here: "
                          f"{'; '.join(differ)}; give the parameter file the designs were chosen with "
                          f"(e.g. {option} gradual_print), or set robot.profile_print to match")


def print_differences(first: typing.Mapping[str, typing.Union[str, float]],
                      second: typing.Mapping[str, typing.Union[str, float]],
                      labels: typing.Tuple[str, str],
                      ignore: typing.AbstractSet[str] = frozenset()) -> typing.List[str]:
    """Each print setting (``print_instructions()`` keys) on which ``first`` and ``second`` differ, as ``"<name>
    <first> (<labels[0]>) vs <second> (<labels[1]>)"``, by name; numbers compare to a relative 1e-9. Empty when they
    agree on every name but ``ignore``."""
    differ = []
    for name in sorted((set(first) | set(second)) - set(ignore)):
        want, have = first.get(name), second.get(name)
        close = (isinstance(want, (int, float)) and isinstance(have, (int, float))
                 and not isinstance(want, bool) and not isinstance(have, bool)
                 and math.isclose(want, have, rel_tol=1e-9, abs_tol=1e-12))
        if not (want == have or close):
            # each at most 40 characters: a goal's 5 MB value was echoed whole into the evaluator's log line
            differ.append(f"{name:.40} {want!s:.40} ({labels[0]}) vs {have!s:.40} ({labels[1]})")
    return differ


def print_instructions_from_text(text: str) -> typing.Dict[str, typing.Union[str, float]]:
    """The print instructions ``text`` carries (a JSON object of setting names to strings or finite numbers, as
    ``json.dumps(print_instructions())`` writes them); ``ValueError`` naming what is wrong otherwise."""
    import json

    try:
        value = json.loads(text)
    except ValueError as exc:
        raise ValueError(f"print instructions are not JSON: {exc}") from None
    except RecursionError:   # 100,000 '[' from a goal's printed_with took the evaluator node down
        raise ValueError("print instructions are not JSON of settings: nested too deep") from None
    if not isinstance(value, dict):
        raise ValueError(f"print instructions must be a JSON object of settings, got {type(value).__name__}")
    for name, item in value.items():
        if isinstance(item, bool) or not isinstance(item, (str, int, float)) \
                or (isinstance(item, float) and not math.isfinite(item)):
            raise ValueError(f"print instruction {name!r} must be a string or a finite number, got {item!r}")
    return value


def configuration_ids(sources: DesignSources) -> typing.List[str]:
    """All ids ``sources`` defines: ``baseline``, the designs file's labels, then the mesh labels.

    Raises ``ValueError`` (:class:`ConfigError` for a bad designs file) when a label is defined twice.
    """
    design_labels = list(_read_designs(_file_version(sources.designs_file))[1]) if sources.designs_file else []
    mesh_labels = list(sources.meshes())
    twice = sorted(set(design_labels) & set(mesh_labels))
    if twice:
        raise ValueError(f"configuration(s) {', '.join(twice)} defined both in {sources.designs_file} and mesh_files")
    return [BASELINE, *design_labels, *mesh_labels]


def profile_mesh_for(configuration: str, sources: DesignSources) -> typing.Optional[geometry.Mesh]:
    """The profile solid (watertight trimesh, metres, profile frame) of ``configuration``; None for the baseline.

    Raises ``ValueError`` naming the known ids for an unknown one, ``FileNotFoundError`` for a missing file and
    :class:`ConfigError` / ``ValueError`` for an unreadable one.
    """
    known = configuration_ids(sources)
    if configuration not in known:
        raise ValueError(f"unknown configuration {configuration!r}: known ids are {', '.join(known)} "
                         "(set launch_twin.designs.designs_file or mesh_labels / mesh_files)")
    if configuration == BASELINE:
        return None
    meshes = sources.meshes()
    if configuration in meshes:
        return _file_mesh(_file_version(meshes[configuration]))
    return _designs_mesh(_file_version(sources.designs_file), configuration)
