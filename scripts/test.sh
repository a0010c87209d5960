#!/usr/bin/env bash
# Sets everything up (scripts/setup.sh), then runs the test suite. Extra arguments go to pytest.
#   ./scripts/test.sh           every test except the minutes-long ones marked `slow` (the README's test command),
#                               spread over the cores (pytest-xdist; add -n 0 to run them in this one process)
#   ./scripts/test.sh --slow    only the `slow` ones (a kill -9 soak, the miniature study end to end and killed twice,
#                               two other robots end to end, the colcon build and its installed executables, and a
#                               second path through a slow set-up: docs/testing.md lists them)
#   ./scripts/test.sh --all     all of them
# .ci/run runs the first two (after a hostile-environment sample), so CI runs every test. No test is rerun
# automatically: a failure is a failure (docs/testing.md); every run ends with `reruns: N` (0 unless --reruns is given).
# The report test opens the HTML report in a real headless browser (Debian's chromium); when chromium is missing
# and this runs as root with apt-get available, it is installed here so nothing needs installing by hand.
set -euo pipefail
repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
# The README's selection runs on one pytest-xdist worker per core (at most 4): each worker is a pytest process of
# its own with its own ROS domain (test/conftest.py), so tests in two workers never see each other's nodes. The
# minutes-long tests run one at a time (-n 0): several of them time a simulated relay board's 250 ms keep-alive.
selection=(-m "not slow" -n auto --maxprocesses 4)
case "${1:-}" in
  --slow) selection=(-m slow -n 0); shift ;;
  --all) selection=(-n 0); shift ;;
esac
"$repo/scripts/setup.sh"
if ! command -v chromium >/dev/null 2>&1 && [ ! -x /usr/bin/chromium ]; then
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
    echo "test: installing Debian's chromium for the report's browser test"
    (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null) \
      || echo "test: warning: could not install chromium; the browser test will say so"
  else
    echo "test: note: chromium is not installed (Debian: apt-get install chromium); the browser test will say so"
  fi
fi
cd "$repo"
exec "$repo/.venv/bin/python" -m pytest ${selection[@]+"${selection[@]}"} "$@"
