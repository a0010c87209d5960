"""Moved to :mod:`rollability_ros.core.records` (the core's shared bottom layer, below every subpackage); this name
stays only for code written against the old path (tests, branches). New code imports ``rollability_ros.core.records``."""
from rollability_ros.core.records import *  # noqa: F401,F403
