"""Moved to :mod:`rollability_ros.core.record_messages` (the core's shared bottom layer, below every subpackage); this name
stays only for code written against the old path (tests, branches). New code imports ``rollability_ros.core.record_messages``."""
from rollability_ros.core.record_messages import *  # noqa: F401,F403
