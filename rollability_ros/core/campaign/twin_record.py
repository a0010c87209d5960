"""What re-simulating a stored launch needs: the launch twin of the campaign's simulated rig, recorded in the run's
info, and the files ``rollability campaign --resimulate`` loads from that record.

The record (run info key :data:`TWIN_RECORD`) lists the twin's parameter files in load order (``rig.twin_config``
as the rig loaded them: each entry as given, the file it named and the SHA-256 of its bytes) and the designs file
and mesh files the twin built its profiles from. A parameter file or designs file inside the store's folder is
recorded relative to that folder, so a study folder moved or copied whole still finds its own files (the designs
file is then given to the twin where it now is); any other file, and every mesh file, by its absolute path.
A re-simulation refuses a recorded file that is missing or whose bytes changed, naming it: it never runs on other
settings than the stored launch's.
"""
import dataclasses
import hashlib
import os
import typing

from rollability_ros.core.config import ConfigError, resolve_config_path

#: Key of the twin record in a campaign run's info.
TWIN_RECORD = "twin"


def file_sha256(path: str) -> str:
    """Hex SHA-256 of the bytes of the file ``path``."""
    digest = hashlib.sha256()
    with open(path, "rb") as stream:
        for block in iter(lambda: stream.read(1 << 16), b""):
            digest.update(block)
    return digest.hexdigest()


def _entry(path: str, base_dir: str, given: str = "") -> typing.Dict[str, str]:
    """``{"given", "path", "sha256"}`` of an existing file; ``path`` relative to ``base_dir`` when inside it."""
    absolute = os.path.abspath(path)
    inside = os.path.commonpath([absolute, base_dir]) == base_dir
    return {"given": given or path, "path": os.path.relpath(absolute, base_dir) if inside else absolute,
            "sha256": file_sha256(absolute)}


def twin_record(twin_config: typing.Sequence[str], design_sources: dict, base_dir: str) -> dict:
    """The record of a simulated rig's twin: its parameter files ``twin_config`` (shipped names or paths, as
    ``rig.twin_config`` lists them) and its ``design_sources`` (:meth:`~rollability_ros.core.rig.launch_backend.
    LaunchBackend.design_sources`), paths relative to ``base_dir`` (the store's folder) when inside it; ``{}`` when a
    file cannot be read (then nothing is recorded and a re-simulation says so)."""
    base_dir = os.path.abspath(base_dir)
    try:
        files = [_entry(resolve_config_path(os.fspath(entry)), base_dir, os.fspath(entry)) for entry in twin_config]
        designs_file = design_sources.get("designs_file", "")
        record: dict = {"files": files}
        if designs_file:
            record["designs_file"] = _entry(designs_file, base_dir)
        record["mesh_files"] = {label: {**_entry(path, base_dir), "path": os.path.abspath(path)}
                                for label, path in design_sources.get("mesh_files", {}).items()}
    except (OSError, ConfigError):
        return {}
    return record


def _digests(record: dict) -> typing.Tuple[object, ...]:
    """The SHA-256s a twin record names, in order (its paths left out)."""
    return ([entry["sha256"] for entry in record.get("files", [])],
            (record.get("designs_file") or {}).get("sha256"),
            {label: entry["sha256"] for label, entry in record.get("mesh_files", {}).items()})


def same_twin(first: dict, second: dict) -> bool:
    """True when two twin records name the same file bytes in the same order (paths aside)."""
    return _digests(first) == _digests(second)


@dataclasses.dataclass(frozen=True)
class RecordedTwin:
    """The twin a re-simulation loads: ``twin_config`` (paths, load order) and the ``designs_file`` its profiles
    come from ("" when none), each checked against its recorded bytes."""

    twin_config: typing.List[str]
    designs_file: str = ""


def _checked(entry: typing.Dict[str, str], base_dir: str, run_id: str, what: str) -> str:
    """The path of a recorded file (relative ones from ``base_dir``), once its bytes are the recorded ones."""
    path = os.path.join(base_dir, entry["path"])
    if not os.path.isfile(path):
        raise ValueError(f"run {run_id}: its {what} {path} (recorded as {entry['given']}) is missing: restore it, or "
                         "give the twin's files with --rig-config")
    if file_sha256(path) != entry["sha256"]:
        raise ValueError(f"run {run_id}: its {what} {path} changed since the campaign (its SHA-256 differs from the "
                         "recorded one): restore it, or give the twin's files with --rig-config")
    return path


def recorded_twin(info: dict, base_dir: str, run_id: str) -> typing.Optional[RecordedTwin]:
    """The twin recorded in a campaign run's ``info`` (relative paths from ``base_dir``, the store's folder), every
    file checked; None when the run recorded none (a run stored before the record existed, or not simulated).
    ``ValueError`` in one line naming a missing or changed file, or a run whose sessions loaded different twins."""
    record = info.get(TWIN_RECORD)
    if not record:
        return None
    if record.get("differs_between_sessions"):
        raise ValueError(f"run {run_id} was launched on different twin files in different sessions: no one set "
                         "re-simulates all its launches; give the twin's files with --rig-config")
    base_dir = os.path.abspath(base_dir)
    files = [_checked(entry, base_dir, run_id, "twin file") for entry in record.get("files", [])]
    designs = record.get("designs_file")
    designs_file = _checked(designs, base_dir, run_id, "designs file") if designs else ""
    for entry in record.get("mesh_files", {}).values():
        _checked(entry, base_dir, run_id, "mesh file")
    return RecordedTwin(files, designs_file)
