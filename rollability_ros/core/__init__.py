"""The pure core of rollability_ros: never imports rclpy, so it runs and is tested without ROS.

Subpackages by domain, bottom first: a module imports from its own subpackage and from those listed before it,
plus the shared modules at this level, the bottom layer that imports no subpackage: ``config`` (parameter files
-> settings), ``safe_yaml`` (the one bounded reader of YAML files), ``optional`` (heavy dependencies named in errors), ``registry`` (the tables of swappable
implementations), ``records`` (the plain records every layer exchanges), ``record_messages`` (their one message
mapping), ``store`` (the durable SQLite store of those records), ``stats`` (binomial intervals, rank correlation)
``campaign_matrix`` (a campaign's experiment matrix, which the robust objective in sim scores over too) and
``faces`` (the lazy subpackage faces). Code outside a subpackage imports it through its face, the ``__init__`` that
lists its public names in ``__all__`` (test/core/test_faces.py).
test/core/test_layering.py checks this order (no new upward import, no new cycle).

- profile       profile geometry, printability, configuration ids -> solids
- robots        the built-in chassis and URDF robots the simulation spawns
- sim           PyBullet worlds, disturbance trials, evaluation, stable-pose screen, launch twin
- optimization  CMA-ES, the run loop and checkpoints, evaluator pool, design selection
- imu           orientation maths, upright classifier, tip-over tracker
- rig           the launch sequence, the valve and its backends, relay simulator, speed gates
- bags          rosbag2/MCAP write, read, recover, convert, playback
- results       the outcome log, CSV, analysis, figures, report
- campaign      experiment matrix, campaign loop, calibration of the twin
- graph         the node graph as processes: command lines, bringup, supervisor, study, live view

Heavy dependencies (pybullet, trimesh, cma, matplotlib, ray) are imported only inside the modules that use them,
through :mod:`rollability_ros.core.optional`, so the rig side runs on a robot computer without them.
"""
