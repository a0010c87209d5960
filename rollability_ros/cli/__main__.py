"""`python -m rollability_ros.cli`: the same as the `rollability` command."""
import sys

from rollability_ros.cli import main

sys.exit(main())
