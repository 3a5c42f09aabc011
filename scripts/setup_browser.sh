#!/usr/bin/env bash
# The browser tests' own needs (marker `browser`, tests/browser): Debian's Chromium, run headless with
# software WebGL. Root (apt). Idempotent.
set -euo pipefail
if ! command -v chromium >/dev/null 2>&1; then
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null
fi
chromium --version
