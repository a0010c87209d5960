"""Optional heavy dependencies, imported only where a feature needs them.

The rig side (valve controller, physical rig, logger, recorder, tip monitor) runs on a robot computer
without pybullet, trimesh, cma, ray or matplotlib; a missing one raises an error naming the extra to install.
"""
import importlib
import types
import typing

#: module name -> the pip extra of rollability_ros that provides it
EXTRA_FOR_MODULE = {
    "pybullet": "sim",
    "pybullet_data": "sim",
    "trimesh": "sim",
    "scipy": "sim",
    "networkx": "sim",
    "lxml": "sim",
    "xacro": "sim",
    "cma": "sim",
    "ribs": "sim",
    "sklearn": "calibration",
    "ray": "cluster",
    "matplotlib": "report",
    "serial": "hardware",
    "gpiod": "hardware",
    "foxglove": "view",
    "rich": "progress",
}


class MissingDependency(ImportError):
    """A feature needs a package that is not installed; the message names the extra that provides it."""


def require(module_name: str, feature: typing.Optional[str] = None) -> types.ModuleType:
    """Import ``module_name`` or raise :class:`MissingDependency` naming the extra to install.

    Parameters
    ----------
    module_name : str
        Importable module name, e.g. ``"pybullet"``.
    feature : str, optional
        What needs it, for the message (e.g. ``"the simulated evaluator"``).
    """
    try:
        return importlib.import_module(module_name)
    except ImportError as exc:
        extra = EXTRA_FOR_MODULE.get(module_name.split(".")[0], "all")
        what = f" for {feature}" if feature else ""
        raise MissingDependency(
            f"'{module_name}' is needed{what} but is not installed: "
            f"pip install 'rollability_ros[{extra}]' (or install {module_name} from your distribution)"
        ) from exc
