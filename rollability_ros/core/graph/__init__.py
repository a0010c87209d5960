"""The node graph as processes: node command lines, bringup settings, the supervisor, the study, live view.

- bringup: the lab session's graph from config/bringup.yaml as node command lines (which node, namespace,
  parameter files)
- supervisor: start, restart and stop a graph of OS processes
- study: the main job through the real graph
- preflight: every node's parameters checked before a study starts any process
- progress: the live status line of study / bringup (plain lines when not a terminal)
- session: a session's own ROS domain (isolation by default), its session.yaml and how a verb joins it
- foxglove_view: the graph's topics served over the Foxglove WebSocket protocol (poses also as /tf)
- _ros_domain: a ROS domain of its own for a test run or a bench (claim_domain), so graphs side by side do not talk

The face is ``__init__.pyi`` beside this file: the names code outside ``core/graph`` imports (``from
rollability_ros.core.graph import <name>``), each with the module it lives in. ``lazy_loader.attach_stub``
(scientific-python SPEC 1) reads it: importing the face loads none of the modules behind it, and a name's
module is imported when the name is first used, so a light caller (the rig computer) never pays for numpy,
physics or plotting. Type checkers read the same stub. test/core/test_faces.py checks both.
"""
import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
