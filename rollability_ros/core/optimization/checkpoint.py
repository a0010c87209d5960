"""Optimizer checkpoints: data only (JSON), checksummed, written atomically after each completed generation.

A checkpoint is a JSON document ``{"sha256": <hex digest of the body>, "checkpoint": body}``; the body holds the
format version, run id, completed generations, the config hash and the merged parameters it was made with, the
optimizer state (:meth:`ProfileOptimizer.state_dict`: the fitnesses told to CMA-ES each generation, from which
the strategy is rebuilt exactly by replaying ask/tell, plus its mean and step size as a check) and the
best-so-far fitness. Nothing in it can run code when loaded (unlike a pickle). The file is written to a
temporary file in the same directory, fsynced, renamed over the old one with ``os.replace`` and the directory
fsynced, so after a ``kill -9`` or a power cut it is either the previous checkpoint or the new one.

The run's store records the SHA-256 of the file it last wrote (:func:`file_sha256`), so a resume can tell the
run's own checkpoint from a damaged, replaced or foreign one (see ``OptimizationRun``).
"""
import hashlib
import json
import os
import typing
from collections.abc import Mapping

from rollability_ros.core.config import ConfigError

#: File name of the checkpoint inside a run directory.
CHECKPOINT_FILENAME = "checkpoint.json"
#: The pickled checkpoint of earlier versions: never loaded (a pickle can run code).
LEGACY_CHECKPOINT_FILENAME = "checkpoint.pkl"
#: Bump when the checkpoint dict changes incompatibly.
CHECKPOINT_FORMAT = 2


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes) -> None:
    """Write ``data`` to ``path`` so that readers and crashes see either the old file or the new one.

    Temp file in the same directory -> write -> fsync -> ``os.replace`` -> fsync of the directory (makes the
    rename itself durable).
    """
    path = os.fspath(path)
    directory = os.path.dirname(os.path.abspath(path))
    temporary = f"{path}.tmp.{os.getpid()}"
    with open(temporary, "wb") as stream:
        stream.write(data)
        stream.flush()
        os.fsync(stream.fileno())
    os.replace(temporary, path)
    descriptor = os.open(directory, os.O_RDONLY)
    try:
        os.fsync(descriptor)
    finally:
        os.close(descriptor)


class Checkpoint(typing.TypedDict):
    """A checkpoint's body (:func:`checkpoint_bytes` writes it, :func:`load_checkpoint` returns it once its format
    and SHA-256 show this code wrote it)."""

    format: int
    run_id: str
    #: The optimizer's generation counter after the checkpointed generation (``optimizer["generation"]``).
    generation: int
    config_hash: str
    #: The run's flat parameters.
    parameters: typing.Dict[str, object]
    #: The optimizer's ``state_dict()``, JSON data its method's ``create(state=...)`` reads back.
    optimizer: typing.Dict[str, object]
    best_so_far: float | None


def config_hash(parameters: Mapping[str, object]) -> str:
    """Return a stable hex digest of a flat ``{dotted name: value}`` parameter dict (order-independent)."""
    text = json.dumps(parameters, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


_UNSET = object()


def _show(value):
    return "(unset)" if value is _UNSET else repr(value)


def parameter_differences(saved: Mapping[str, object], current: Mapping[str, object]) -> list[str]:
    """Return ``["name: saved -> current", ...]`` for every parameter that differs (added, removed or changed)."""
    lines = []
    for name in sorted(set(saved) | set(current)):
        before, after = saved.get(name, _UNSET), current.get(name, _UNSET)
        if before != after:
            lines.append(f"{name}: {_show(before)} -> {_show(after)}")
    return lines


def _canonical(body):
    return json.dumps(body, sort_keys=True, separators=(",", ":"), allow_nan=False, default=str).encode("utf-8")


def checkpoint_bytes(run_id: str, parameters: Mapping[str, object], optimizer_state: Mapping[str, object],
                     best_so_far: float | None) -> bytes:
    """Return the checkpoint file's bytes (JSON) for ``run_id`` after ``optimizer_state["generation"]``."""
    generation = optimizer_state["generation"]
    if isinstance(generation, bool) or not isinstance(generation, int):
        raise ValueError(f"optimizer state's generation must be an integer, got {generation!r}")
    body = Checkpoint(format=CHECKPOINT_FORMAT, run_id=run_id, generation=generation,
                      config_hash=config_hash(parameters), parameters=dict(parameters),
                      optimizer=dict(optimizer_state), best_so_far=best_so_far)
    canonical = _canonical(body)
    return _canonical({"sha256": hashlib.sha256(canonical).hexdigest(), "checkpoint": json.loads(canonical)})


def save_checkpoint(path: str | os.PathLike[str], run_id: str, parameters: Mapping[str, object],
                    optimizer_state: Mapping[str, object], best_so_far: float | None) -> str:
    """Atomically write the checkpoint of ``run_id``; return the SHA-256 hex digest of the file written."""
    data = checkpoint_bytes(run_id, parameters, optimizer_state, best_so_far)
    atomic_write_bytes(path, data)
    return hashlib.sha256(data).hexdigest()


def file_sha256(path: str | os.PathLike[str]) -> str:
    """SHA-256 hex digest of the file at ``path``."""
    with open(path, "rb") as stream:
        return hashlib.sha256(stream.read()).hexdigest()


def load_checkpoint(path: str | os.PathLike[str]) -> Checkpoint | None:
    """Return the checkpoint body at ``path``, or None if there is none; ``ValueError`` naming why it is unusable
    (not JSON, checksum mismatch, wrong format). Only parses data: nothing in the file is executed."""
    try:
        with open(path, "rb") as stream:
            data = stream.read()
    except FileNotFoundError:
        return None
    try:
        document = json.loads(data.decode("utf-8"))
    except (UnicodeDecodeError, ValueError, RecursionError) as exc:   # RecursionError: nesting too deep
        raise ValueError(f"checkpoint {path} is damaged or not a checkpoint (not JSON: {exc})") from exc
    if not isinstance(document, dict) or not isinstance(document.get("checkpoint"), dict):
        raise ValueError(f"checkpoint {path} is not a checkpoint of this code (no checkpoint body)")
    body = document["checkpoint"]
    found = body.get("format")
    if found != CHECKPOINT_FORMAT:
        raise ValueError(f"checkpoint {path} has format {found!r}, this code reads format {CHECKPOINT_FORMAT}")
    if hashlib.sha256(_canonical(body)).hexdigest() != document.get("sha256"):
        raise ValueError(f"checkpoint {path} is damaged: its content does not match its own SHA-256")
    return body


def check_same_config(checkpoint: Checkpoint, parameters: Mapping[str, object],
                      path: str | os.PathLike[str]) -> None:
    """Raise :class:`ConfigError` listing the differing parameters if ``parameters`` differ from the checkpoint's."""
    if checkpoint["config_hash"] == config_hash(parameters):
        return
    differences = parameter_differences(checkpoint["parameters"], parameters)
    raise ConfigError(f"cannot resume run {checkpoint['run_id']}: the configuration differs from the one in {path} "
                      f"({len(differences)} parameter(s): {'; '.join(differences[:8])}"
                      f"{'; ...' if len(differences) > 8 else ''}); resume with the run's own config.yaml")
