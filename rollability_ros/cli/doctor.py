"""`rollability doctor`: check the installation and the ROS environment, in plain words."""
import argparse
import importlib
import importlib.metadata
import os
import platform
import sys

from rollability_ros.cli import Subparsers

#: (module, distribution, extra, needed on the rig side)
PACKAGES = (
    ("numpy", "numpy", None, True),
    ("yaml", "PyYAML", None, True),
    ("mcap", "mcap", None, True),
    ("mcap_ros2", "mcap-ros2-support", None, True),
    ("rosbags", "rosbags", None, True),
    ("pybullet", "pybullet", "sim", False),
    ("cma", "cma", "sim", False),
    ("trimesh", "trimesh", "sim", False),
    ("scipy", "scipy", "sim", False),
    ("networkx", "networkx", "sim", False),
    ("matplotlib", "matplotlib", "report", False),
    ("ray", "ray", "cluster", False),
    ("serial", "pyserial", "hardware", True),
    ("foxglove", "foxglove-sdk", "view", False),
)


class Checks:
    """Collects check results and prints one line each: ok / warn / FAIL."""

    def __init__(self):
        self.failures = 0
        self.warnings = 0

    def report(self, status: str, what: str, detail: str) -> None:
        if status == "FAIL":
            self.failures += 1
        elif status == "warn":
            self.warnings += 1
        print(f"  {status:<4}  {what:<28} {detail}")


def _version(distribution):
    try:
        return importlib.metadata.version(distribution)
    except importlib.metadata.PackageNotFoundError:
        return "unknown version"


def _check_python(checks):
    version = platform.python_version()
    if sys.version_info >= (3, 11):
        checks.report("ok", "Python", f"{version} ({sys.executable})")
    else:
        checks.report("FAIL", "Python", f"{version}: rollability_ros needs Python 3.11 or newer")


def _check_ros(checks):
    try:
        import rclpy
    except ImportError as exc:
        checks.report("FAIL", "rclpy", f"cannot import rclpy ({exc}): run scripts/setup.sh, or source /opt/ros/jazzy/setup.bash")
        return False
    checks.report("ok", "rclpy", f"imported from {os.path.dirname(rclpy.__file__)}")
    from rclpy.utilities import get_rmw_implementation_identifier

    try:
        context = rclpy.Context()
        rclpy.init(context=context, args=[])
        try:
            rmw = get_rmw_implementation_identifier()
        finally:
            rclpy.shutdown(context=context)
        checks.report("ok", "RMW implementation", f"{rmw} (initialised a context)")
    except Exception as exc:  # the RMW library failing to load surfaces as several exception types
        checks.report("FAIL", "RMW implementation", f"{os.environ.get('RMW_IMPLEMENTATION', 'default')} does not load: {exc}")
        return False
    return True


def _check_interfaces(checks):
    try:
        from rclpy.serialization import deserialize_message, serialize_message

        from rollability_ros.action import EvaluateProfile, Launch
        from rollability_ros.msg import CandidateResult, LaunchOutcome, ValveState
        from rollability_ros.srv import ArmValve, ConfirmRegulator, FireValve, RecordOutcome

        outcome = LaunchOutcome(trial_id="doctor", upright=True)
        roundtrip = deserialize_message(serialize_message(outcome), LaunchOutcome)
        if roundtrip.trial_id != "doctor":
            raise RuntimeError("LaunchOutcome did not survive a CDR round trip")
        loaded = [CandidateResult, ValveState, ArmValve, FireValve, RecordOutcome, ConfirmRegulator, EvaluateProfile,
                  Launch]
        checks.report("ok", "custom interfaces", f"{len(loaded) + 1} types load; LaunchOutcome round-trips through CDR")
    except Exception as exc:
        checks.report("FAIL", "custom interfaces", f"{exc}: build them with scripts/setup.sh or colcon build")


def _check_packages(checks, rig_only):
    for module, distribution, extra, rig_side in PACKAGES:
        if rig_only and not rig_side:
            continue
        try:
            importlib.import_module(module)
        except ImportError:
            hint = f"pip install 'rollability_ros[{extra}]'" if extra else f"pip install {distribution}"
            status = "FAIL" if (rig_side or not rig_only) and extra != "view" else "warn"
            checks.report(status, distribution, f"not installed: {hint}")
            continue
        checks.report("ok", distribution, _version(distribution))


def _check_discovery(checks):
    domain = os.environ.get("ROS_DOMAIN_ID", "")
    if domain == "":
        checks.report("ok", "ROS_DOMAIN_ID", "unset: domain 0 (every ROS 2 machine on the network shares it)")
    elif domain.isdigit() and 0 <= int(domain) <= 232:
        note = "" if int(domain) <= 101 else " (above 101 the DDS ports may collide with ephemeral ports)"
        checks.report("ok" if not note else "warn", "ROS_DOMAIN_ID", domain + note)
    else:
        checks.report("FAIL", "ROS_DOMAIN_ID", f"{domain!r} is not an integer in 0..232")
    scope = os.environ.get("ROS_AUTOMATIC_DISCOVERY_RANGE", "")
    peers = os.environ.get("ROS_STATIC_PEERS", "")
    meaning = {
        "": "unset: SUBNET (finds nodes on this machine and the local network)",
        "SUBNET": "SUBNET (this machine and the local network)",
        "LOCALHOST": "LOCALHOST (nodes on this machine only)",
        "OFF": "OFF (no automatic discovery; static peers only)",
        "SYSTEM_DEFAULT": "SYSTEM_DEFAULT (the middleware's own setting)",
    }
    if scope in meaning:
        checks.report("ok", "discovery range", meaning[scope] + (f"; static peers {peers}" if peers else ""))
    else:
        checks.report("FAIL", "discovery range", f"ROS_AUTOMATIC_DISCOVERY_RANGE={scope!r} is not one of SUBNET, LOCALHOST, OFF, SYSTEM_DEFAULT")
    if os.environ.get("ROS_LOCALHOST_ONLY"):
        checks.report("warn", "ROS_LOCALHOST_ONLY", "deprecated in Jazzy: use ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST")


def _check_rig_exposure(checks):
    """On the rig computer: warn when other computers' ROS 2 processes can discover the valve_controller."""
    from rollability_ros.core.rig import exposure_warnings

    warnings = exposure_warnings(os.environ)
    for warning in warnings:
        checks.report("warn", "rig exposure", warning)
    if not warnings:
        checks.report("ok", "rig exposure", "own domain, discovery limited to this machine")


def _check_config(checks):
    from rollability_ros.core.config import ConfigError, config_dir

    try:
        checks.report("ok", "config files", config_dir())
    except ConfigError as exc:
        checks.report("FAIL", "config files", str(exc))


def run(args: argparse.Namespace) -> int:
    """Run every check; exit code 0 when nothing failed."""
    checks = Checks()
    print("rollability doctor" + (" (rig side only)" if args.rig else ""))
    _check_python(checks)
    if _check_ros(checks):
        _check_interfaces(checks)
    _check_packages(checks, args.rig)
    _check_discovery(checks)
    if args.rig:
        _check_rig_exposure(checks)
    _check_config(checks)
    if checks.failures:
        print(f"{checks.failures} check(s) failed, {checks.warnings} warning(s).")
        return 1
    print(f"all checks passed ({checks.warnings} warning(s)).")
    return 0


def register(subparsers: Subparsers) -> None:
    parser = subparsers.add_parser(
        "doctor",
        help="check Python, rclpy, the RMW, the custom interfaces, dependencies and ROS discovery settings",
        description="Check the installation and the ROS environment and report each item in plain words. "
        "Exit code 0 when every check passed.",
    )
    parser.add_argument("--rig", action="store_true",
                        help="check only what the rig side needs (robot computer without the simulation extras)")
    parser.set_defaults(func=run)
