"""Optimizer checkpoints: written atomically after each completed generation, checked against the run's config.

A checkpoint is a pickled dict: format version, run id, completed generations, the config hash and the merged
parameters it was made with, the optimizer state (:meth:`ProfileOptimizer.state_dict`: pickled pycma strategy,
its numpy RNG state, counters, incumbent) and the best-so-far fitness. It is written to a temporary file in the
same directory, fsynced, renamed over the old one with ``os.replace`` and the directory fsynced, so after a
``kill -9`` or a power cut the file is either the previous checkpoint or the new one, never a torn mix.

Pickle is used because pycma's strategy object is only serialisable that way; load checkpoints you made.
"""
import hashlib
import json
import os
import pickle

from rollability_ros.core.config import ConfigError

#: File name of the checkpoint inside a run directory.
CHECKPOINT_FILENAME = "checkpoint.pkl"
#: Bump when the checkpoint dict changes incompatibly.
CHECKPOINT_FORMAT = 1


def atomic_write_bytes(path, data):
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


def config_hash(parameters):
    """Return a stable hex digest of a flat ``{dotted name: value}`` parameter dict (order-independent)."""
    text = json.dumps(parameters, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


_UNSET = object()


def _show(value):
    return "(unset)" if value is _UNSET else repr(value)


def parameter_differences(saved, current):
    """Return ``["name: saved -> current", ...]`` for every parameter that differs (added, removed or changed)."""
    lines = []
    for name in sorted(set(saved) | set(current)):
        before, after = saved.get(name, _UNSET), current.get(name, _UNSET)
        if before != after:
            lines.append(f"{name}: {_show(before)} -> {_show(after)}")
    return lines


def save_checkpoint(path, run_id, parameters, optimizer_state, best_so_far):
    """Atomically write the checkpoint of ``run_id`` after ``optimizer_state["generation"]`` generations."""
    checkpoint = {"format": CHECKPOINT_FORMAT, "run_id": run_id, "generation": optimizer_state["generation"],
                  "config_hash": config_hash(parameters), "parameters": dict(parameters),
                  "optimizer": optimizer_state, "best_so_far": best_so_far}
    atomic_write_bytes(path, pickle.dumps(checkpoint, protocol=pickle.HIGHEST_PROTOCOL))


def load_checkpoint(path):
    """Return the checkpoint dict at ``path``, or None if there is none; ``ValueError`` if it is unusable."""
    try:
        with open(path, "rb") as stream:
            checkpoint = pickle.load(stream)
    except FileNotFoundError:
        return None
    except (pickle.UnpicklingError, EOFError, AttributeError, ImportError) as exc:
        raise ValueError(f"checkpoint {path} is unreadable ({exc}); it was not written by this code") from exc
    found = checkpoint.get("format") if isinstance(checkpoint, dict) else None
    if found != CHECKPOINT_FORMAT:
        raise ValueError(f"checkpoint {path} has format {found!r}, this code reads format {CHECKPOINT_FORMAT}")
    return checkpoint


def check_same_config(checkpoint, parameters, path):
    """Raise :class:`ConfigError` listing the differing parameters if ``parameters`` differ from the checkpoint's."""
    if checkpoint["config_hash"] == config_hash(parameters):
        return
    differences = parameter_differences(checkpoint["parameters"], parameters)
    raise ConfigError(f"cannot resume run {checkpoint['run_id']}: the configuration differs from the one in {path} "
                      f"({len(differences)} parameter(s): {'; '.join(differences[:8])}"
                      f"{'; ...' if len(differences) > 8 else ''}); resume with the run's own config.yaml")
