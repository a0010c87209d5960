"""The face of ``rollability_ros.core.graph``: the names code outside the subpackage imports, and where each
lives. Type checkers read this stub; at run time ``lazy_loader.attach_stub`` (``__init__.py``) reads the same
imports and loads a name's module when the name is first used."""
from .bringup import (GraphSettings, NodeLaunch, add_twin_files, join_nodes, load_graph_settings, new_study_id,
                      parameter_files, session_nodes)
from .foxglove_view import ViewServer, ViewSettings, parse_pose_frames
from .preflight import check_graph_parameters, graph_namespaces, refuse_bad_session
from .progress import GraphObserver, ProgressDisplay, session_progress
from .session import SESSION_FILE, SessionInfo, load_session, start_session
from .study import PROGRESS_PERIOD_S, Study, StudyConfig, study_config
from .supervisor import ProcessSpec, Supervisor
from ._ros_domain import claim_domain

__all__ = [
    "PROGRESS_PERIOD_S", "SESSION_FILE", "GraphObserver", "GraphSettings", "NodeLaunch", "ProcessSpec",
    "ProgressDisplay", "SessionInfo", "Study", "StudyConfig", "Supervisor", "ViewServer", "ViewSettings",
    "add_twin_files", "check_graph_parameters", "claim_domain", "graph_namespaces", "join_nodes", "load_graph_settings",
    "load_session", "new_study_id", "parameter_files", "parse_pose_frames", "refuse_bad_session", "session_nodes",
    "session_progress", "start_session", "study_config"
]
