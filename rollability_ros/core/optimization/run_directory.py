"""Where an optimization run lives and what it is given: the run directory (``<output_dir>/<run_id>/``, its
``config.yaml`` of merged parameters) and the parameter files a run is loaded from. :func:`run_target` is the one
resolution of which run to start or continue that ``rollability optimize`` and the ``optimizer`` node share;
:class:`~rollability_ros.core.optimization.optimization_run.OptimizationRun` writes and checks the directory
through these functions."""
import os
import time
import typing

import yaml

from rollability_ros.core.config import check_path_component, load_parameters, parameter_document, resolve_config_path
from rollability_ros.core.optimization.checkpoint import atomic_write_bytes

#: File name of the merged parameters inside a run directory.
RUN_CONFIG_FILENAME = "config.yaml"
#: The parameter naming the folder runs are kept in (not a setting of the run itself).
OUTPUT_DIR_PARAMETER = "optimizer.output_dir"
#: ``kind`` of optimization runs in the store's run table.
RUN_KIND = "optimization"
#: Parameter files every optimization config is loaded on top of (the evaluator's settings).
BASE_CONFIGS = ("sim", "robot", "evaluator")


def new_run_id(now_s: typing.Optional[float] = None) -> str:
    """Return a run id from the local time, ``opt-YYYYmmdd-HHMMSS``."""
    return time.strftime("opt-%Y%m%d-%H%M%S", time.localtime(time.time() if now_s is None else now_s))


#: The shipped optimiser defaults, loaded under the given files unless they name an optimiser file themselves.
OPTIMIZER_CONFIGS = ("optimizer", "paper")


def load_run_parameters(config_paths: typing.Union[str, os.PathLike, typing.Sequence]) -> dict:
    """Merge :data:`BASE_CONFIGS` and ``config_paths`` (one or a list of paths or shipped names such as
    ``"paper"``; later files win, e.g. ``["optimizer", "runs/cal/calibrated.yaml"]``). Unless the list names a
    shipped optimiser file (:data:`OPTIMIZER_CONFIGS`), ``config/optimizer.yaml`` goes first: a robot config
    alone (``--config robot.yaml``) runs on the shipped defaults, and its own ``optimizer`` keys win."""
    if isinstance(config_paths, (str, os.PathLike)):
        config_paths = [config_paths]
    config_paths = list(config_paths)
    shipped = {os.path.abspath(resolve_config_path(name)) for name in OPTIMIZER_CONFIGS}
    named = any(os.path.abspath(resolve_config_path(path)) in shipped for path in config_paths)
    defaults = [] if named else [OPTIMIZER_CONFIGS[0]]
    return load_parameters(list(BASE_CONFIGS) + defaults + config_paths)


def resolve_run_dir(run: typing.Union[str, os.PathLike], output_dir: str = "runs") -> str:
    """Return the directory of ``run``: a run directory path as given, else ``<output_dir>/<run>``."""
    if os.path.isfile(os.path.join(run, RUN_CONFIG_FILENAME)):
        return os.fspath(run)
    return os.path.join(output_dir, run)


def run_id_of(run_dir: typing.Union[str, os.PathLike]) -> str:
    """The run id of a run directory: its name."""
    return os.path.basename(os.path.normpath(os.fspath(run_dir)))


def write_run_config(path: typing.Union[str, os.PathLike], parameters: dict) -> None:
    """Write flat ``parameters`` as a ROS 2 parameter file (``/**: {ros__parameters: {...}}``), atomically."""
    text = yaml.safe_dump(parameter_document(parameters), sort_keys=True)
    atomic_write_bytes(path, text.encode("utf-8"))


def check_new_run_dir(run_dir: str) -> None:
    """Raise ValueError when ``run_dir`` exists and is not an empty folder: a new run never writes into a folder
    that holds anything (another run, a study, files of the user), so a refused start leaves it as it was."""
    if os.path.lexists(run_dir) and not (os.path.isdir(run_dir) and not os.listdir(run_dir)):
        what = ("run" if os.path.isfile(os.path.join(run_dir, RUN_CONFIG_FILENAME)) else "folder")
        raise ValueError(f"{what} {run_dir} already exists; resume it (--resume) or choose another run id"
                         if what == "run" else f"{run_dir} already exists and is not an empty folder; choose "
                         "another run id")


def run_target(run_id: str, resume: bool, parameters: typing.Optional[dict],
               output_dir: str = "runs") -> typing.Tuple[str, dict]:
    """``(run_dir, parameters)`` of the run to start or continue: the one resolution the CLI and the node share.

    A new run needs ``parameters`` and lives in ``<output_dir>/<run_id>`` (``run_id`` "" -> :func:`new_run_id`).
    Resuming needs ``run_id`` (an id under ``output_dir`` or a run directory); its saved ``config.yaml`` is used
    with ``parameters`` (if any) on top, so :class:`OptimizationRun` refuses a resume whose settings differ.
    """
    if not resume:
        if parameters is None:
            raise ValueError("a new run needs its parameters (e.g. --config optimizer, --config paper)")
        run_id = check_path_component(run_id, "the run id") if run_id else new_run_id()
        run_dir = os.path.join(output_dir, run_id)
        check_new_run_dir(run_dir)
        return run_dir, dict(parameters)
    if not run_id:
        raise ValueError("resume needs the run id (or directory) of the run to continue")
    run_dir = resolve_run_dir(run_id, output_dir)
    return run_dir, {**read_run_config(run_dir), **(parameters or {})}


def read_run_config(run_dir: typing.Union[str, os.PathLike]) -> dict:
    """Return the flat parameters saved in ``<run_dir>/config.yaml``; ``FileNotFoundError`` if it is not a run."""
    path = os.path.join(run_dir, RUN_CONFIG_FILENAME)
    if not os.path.isfile(path):
        raise FileNotFoundError(f"{run_dir} is not an optimization run (no {RUN_CONFIG_FILENAME})")
    return load_parameters(path)
