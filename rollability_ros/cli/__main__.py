"""`python -m rollability_ros.cli`: the same as the `rollability` command."""
import sys

from rollability_ros.cli import main

if __name__ == "__main__":
    sys.exit(main())
