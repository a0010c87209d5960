"""The face of ``rollability_ros.core.rig``: the names code outside the subpackage imports, and where each
lives. Type checkers read this stub; at run time ``lazy_loader.attach_stub`` (``__init__.py``) reads the same
imports and loads a name's module when the name is first used."""
from .launch_backend import (LAUNCH_BACKENDS, LaunchAborted, LaunchBackend, OperatorOutcome, RigPorts, RigSettings,
                             describe_answer, parse_outcome_answer)
from .launched_twin import (NO_TWIN, TWIN_RECORD, file_sha256, launched_twin, merge_twin, same_twin, stored_twin,
                            twin_from_text, twin_to_text)
from .rig_auth import KeyFileSigner, RecordGuard, request_guard
from .rig_network import (DISCOVERY_RANGES, RIG_DOMAIN_ID, check_domain_id, check_namespace, exposure_warnings,
                          physical_rig_environment)
from .outcome_sources import ImuOutcome, check_rest_distance, simulated_continuous_outcomes
from .rig_session import (ANSWERED, ASK_OUTCOME, ASK_REGULATOR, PhysicalLaunch, SimulatedLaunch, launch_backend_class,
                          make_launch_backend)
from .speed_gate import SPEED_GATES, SpeedGate, SpeedGateConfig, make_speed_gate
from .valve import ValveController, ValveStatus
from .valve_auth import (AuthError, RequestSigner, RequestVerifier, Signature, create_session_key, default_key_path,
                         load_session_key, remove_session_key)
from .valve_boards import make_controller
from .valve_contract import VALVE_BACKENDS, ValveBackend, ValveConfig, make_valve_backend, register_valve_backend

__all__ = [
    "ANSWERED", "ASK_OUTCOME", "ASK_REGULATOR", "DISCOVERY_RANGES", "LAUNCH_BACKENDS", "NO_TWIN", "RIG_DOMAIN_ID",
    "SPEED_GATES", "TWIN_RECORD", "VALVE_BACKENDS", "AuthError", "ImuOutcome", "KeyFileSigner", "LaunchAborted",
    "LaunchBackend", "OperatorOutcome", "PhysicalLaunch", "RecordGuard", "RequestSigner", "RequestVerifier",
    "RigPorts", "RigSettings", "Signature", "SimulatedLaunch", "SpeedGate", "SpeedGateConfig", "ValveBackend",
    "ValveConfig", "ValveController", "ValveStatus", "check_domain_id", "check_namespace", "check_rest_distance",
    "create_session_key", "default_key_path", "describe_answer", "exposure_warnings", "file_sha256",
    "launch_backend_class", "launched_twin", "load_session_key", "make_controller", "make_launch_backend",
    "make_speed_gate", "make_valve_backend", "merge_twin", "parse_outcome_answer", "physical_rig_environment",
    "register_valve_backend", "remove_session_key", "request_guard", "same_twin", "simulated_continuous_outcomes",
    "stored_twin", "twin_from_text", "twin_to_text"
]
