"""The node graph as processes: node command lines, bringup settings, the supervisor, the study, live view.

- bringup: the lab session's graph from config/bringup.yaml as node command lines (which node, namespace,
  parameter files)
- supervisor: start, restart and stop a graph of OS processes
- study: the main job through the real graph
- preflight: every node's parameters checked before a study starts any process
- progress: the live status line of study / bringup (plain lines when not a terminal)
- session: a session's own ROS domain (isolation by default), its session.yaml and how a verb joins it
- foxglove_view: the graph's topics served over the Foxglove WebSocket protocol (poses also as /tf)

The face below is what code outside ``core/graph`` imports (``from rollability_ros.core.graph import Study``). It is
lazy (``core/faces.py``): importing it loads none of the modules behind it, and a name's module is imported when the
name is first used, so a light caller never pays for the parts of the graph it does not use.
"""
import typing

from rollability_ros.core.faces import lazy_attribute

if typing.TYPE_CHECKING:   # imported when first used: lazy_attribute reads this block
    from rollability_ros.core.graph.bringup import (GraphSettings, NodeLaunch, add_twin_files, join_nodes,
                                                    load_graph_settings, new_study_id, parameter_files, session_nodes)
    from rollability_ros.core.graph.foxglove_view import ViewServer, ViewSettings, parse_pose_frames
    from rollability_ros.core.graph.preflight import check_graph_parameters, graph_namespaces, refuse_bad_session
    from rollability_ros.core.graph.progress import GraphObserver, ProgressDisplay, session_progress
    from rollability_ros.core.graph._ros_domain import claim_domain
    from rollability_ros.core.graph.session import SESSION_FILE, SessionInfo, load_session, start_session
    from rollability_ros.core.graph.study import PROGRESS_PERIOD_S, Study
    from rollability_ros.core.graph.supervisor import ProcessSpec, Supervisor

__all__ = [
    "PROGRESS_PERIOD_S", "SESSION_FILE", "GraphObserver", "GraphSettings", "NodeLaunch", "ProcessSpec",
    "ProgressDisplay", "SessionInfo", "Study", "Supervisor", "ViewServer", "ViewSettings", "add_twin_files",
    "check_graph_parameters", "claim_domain", "graph_namespaces", "join_nodes", "load_graph_settings", "load_session",
    "new_study_id", "parameter_files", "parse_pose_frames", "refuse_bad_session", "session_nodes", "session_progress",
    "start_session",
]


def __getattr__(name: str) -> typing.Any:
    return lazy_attribute(__name__, name)
