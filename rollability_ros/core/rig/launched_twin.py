"""The launch twin a rig launches in, as the run's info records it (key :data:`TWIN_RECORD`), so that
``rollability campaign --resimulate`` reproduces a stored launch on the same files.

The record lists the twin's parameter files in load order (``rig.twin_config`` as the rig loaded them: each entry
as given, the file it named and the SHA-256 of its bytes) and the designs file and mesh files the twin built its
profiles from. The rig makes it (:func:`launched_twin`, every path absolute on the rig's computer): in process the
campaign files it in the store itself, through the node graph the rig node sends it with each launch outcome
(``LaunchOutcome.twin``, JSON: :func:`twin_to_text`) and the outcome_logger, which owns the store, files it
(:func:`merge_twin`) without reading the rig's files. Filed, a parameter file or designs file inside the store's
folder is recorded relative to that folder, so a study folder moved or copied whole still finds its own files;
any other file, and every mesh file, by its absolute path. A rig that simulates nothing (the physical launcher)
records ``{NO_TWIN: backend}``: a re-simulation of its run is refused, saying the run was launched on that rig.
"""
import hashlib
import json
import os
import typing

from rollability_ros.core.config import ConfigError, resolve_config_path

#: Key of the twin record in a campaign run's info.
TWIN_RECORD = "twin"
#: Key of a twin record that says the run's rig simulated nothing: ``{NO_TWIN: backend}`` (e.g. ``"physical"``).
NO_TWIN = "no_twin"


def file_sha256(path: str) -> str:
    """Hex SHA-256 of the bytes of the file ``path``."""
    digest = hashlib.sha256()
    with open(path, "rb") as stream:
        for block in iter(lambda: stream.read(1 << 16), b""):
            digest.update(block)
    return digest.hexdigest()


def _entry(path: str, given: str = "") -> typing.Dict[str, str]:
    """``{"given", "path", "sha256"}`` of an existing file, ``path`` absolute."""
    absolute = os.path.abspath(path)
    return {"given": given or path, "path": absolute, "sha256": file_sha256(absolute)}


def launched_twin(backend: str, twin_config: typing.Sequence[str], design_sources: dict) -> dict:
    """The rig's own record of the twin it launches in: its parameter files ``twin_config`` (shipped names or paths,
    as ``rig.twin_config`` lists them) and its ``design_sources`` (:meth:`~rollability_ros.core.rig.launch_backend.
    LaunchBackend.design_sources`), every path absolute; ``{NO_TWIN: backend}`` for a rig that simulates nothing
    (no ``twin_config``); ``{}`` when a file cannot be read (then nothing is recorded and a re-simulation says
    so)."""
    if not twin_config:
        return {NO_TWIN: backend}
    try:
        record: dict = {"files": [_entry(resolve_config_path(os.fspath(entry)), os.fspath(entry))
                                  for entry in twin_config]}
        designs_file = design_sources.get("designs_file", "")
        if designs_file:
            record["designs_file"] = _entry(designs_file)
        record["mesh_files"] = {label: _entry(path) for label, path in design_sources.get("mesh_files", {}).items()}
    except (OSError, ConfigError):
        return {}
    return record


def _filed(entry: typing.Dict[str, str], base_dir: str) -> typing.Dict[str, str]:
    """``entry`` with its absolute path made relative to ``base_dir`` when inside it."""
    path = entry["path"]
    inside = os.path.isabs(path) and os.path.commonpath([path, base_dir]) == base_dir
    return {**entry, "path": os.path.relpath(path, base_dir)} if inside else dict(entry)


def stored_twin(launched: dict, base_dir: str) -> dict:
    """A rig's :func:`launched_twin` as a run's info keeps it: parameter files and designs file inside
    ``base_dir`` (the store's folder) relative to it; mesh files absolute. Reads no file."""
    base_dir = os.path.abspath(base_dir)
    if not launched or NO_TWIN in launched:
        return dict(launched)
    record: dict = {"files": [_filed(entry, base_dir) for entry in launched.get("files", [])]}
    if launched.get("designs_file"):
        record["designs_file"] = _filed(launched["designs_file"], base_dir)
    record["mesh_files"] = {label: dict(entry) for label, entry in launched.get("mesh_files", {}).items()}
    return record


def merge_twin(info: dict, launched: dict, base_dir: str) -> bool:
    """File a rig's :func:`launched_twin` in a run's ``info`` (:data:`TWIN_RECORD`, relative to ``base_dir``, the
    store's folder), where the files are now when an earlier session's record names the same bytes; marks a twin that differs
    (``differs_between_sessions``: no one twin re-simulates the run). True when ``info`` changed."""
    twin = stored_twin(launched, base_dir)
    if not twin:
        return False
    earlier = info.get(TWIN_RECORD)
    if earlier and (earlier.get("differs_between_sessions") or not same_twin(earlier, twin)):
        twin = {"differs_between_sessions": True}
    if earlier == twin:
        return False
    info[TWIN_RECORD] = twin
    return True


def twin_to_text(launched: dict) -> str:
    """A rig's :func:`launched_twin` as the JSON text ``LaunchOutcome.twin`` carries ("" for none)."""
    return json.dumps(launched, sort_keys=True, separators=(",", ":")) if launched else ""


def _checked_entry(entry: object) -> bool:
    return isinstance(entry, dict) and all(isinstance(entry.get(key), str) for key in ("given", "path", "sha256"))


def twin_from_text(text: str) -> dict:
    """The :func:`launched_twin` a ``LaunchOutcome.twin`` carries (``{}`` for ""); ``ValueError`` in one line when
    it is not one (not JSON, or a file entry without its given name, path and SHA-256)."""
    if not text:
        return {}
    try:
        launched = json.loads(text)
    except ValueError:
        raise ValueError("twin: not JSON") from None
    if not isinstance(launched, dict):
        raise ValueError("twin: not a JSON object")
    if NO_TWIN in launched:
        if not isinstance(launched[NO_TWIN], str) or len(launched) != 1:
            raise ValueError(f"twin: {NO_TWIN} names a backend and nothing else")
        return launched
    files, designs, meshes = launched.get("files"), launched.get("designs_file"), launched.get("mesh_files", {})
    if not isinstance(files, list) or not files or not all(_checked_entry(entry) for entry in files):
        raise ValueError("twin: files must list each parameter file's given name, path and sha256")
    if designs is not None and not _checked_entry(designs):
        raise ValueError("twin: designs_file must give its given name, path and sha256")
    if not isinstance(meshes, dict) or not all(_checked_entry(entry) for entry in meshes.values()):
        raise ValueError("twin: mesh_files must map each label to its given name, path and sha256")
    return launched


def _digests(record: dict) -> typing.Tuple[object, ...]:
    """The SHA-256s a twin record names, in order (its paths left out)."""
    return (record.get(NO_TWIN), [entry["sha256"] for entry in record.get("files", [])],
            (record.get("designs_file") or {}).get("sha256"),
            {label: entry["sha256"] for label, entry in record.get("mesh_files", {}).items()})


def same_twin(first: dict, second: dict) -> bool:
    """True when two twin records name the same file bytes in the same order (paths aside)."""
    return _digests(first) == _digests(second)


