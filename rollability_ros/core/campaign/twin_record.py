"""What re-simulating a stored launch needs: the launch twin of the campaign's rig, recorded in the run's info
(:mod:`rollability_ros.core.rig.launched_twin`: the rig's files, filed relative to the store's folder), and the
files ``rollability campaign --resimulate`` loads from that record.

A re-simulation refuses a recorded file that is missing or whose bytes changed, naming it: it never runs on other
settings than the stored launch's. A run whose rig simulated nothing (the physical launcher) is refused, saying so.
"""
import dataclasses
import os
import typing

from rollability_ros.core.rig import NO_TWIN, TWIN_RECORD, file_sha256


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
    if record.get(NO_TWIN):
        raise ValueError(f"run {run_id} was launched on the {record[NO_TWIN]} rig, not on a twin: no twin files to "
                         "re-simulate it on; give the twin's files with --rig-config to simulate its conditions")
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
