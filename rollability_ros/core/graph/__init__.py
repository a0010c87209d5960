"""The node graph as processes: node command lines, bringup settings, the supervisor, the study, live view.

- bringup: the lab session's graph from config/bringup.yaml as node command lines (which node, namespace,
  parameter files)
- supervisor: start, restart and stop a graph of OS processes
- study: the main job through the real graph
- preflight: every node's parameters checked before a study starts any process
- progress: the live status line of study / bringup (plain lines when not a terminal)
- foxglove_view: the graph's topics served over the Foxglove WebSocket protocol (poses also as /tf)
"""
