#!/usr/bin/env bash
# Set up the independent TCPCLv4 peer of the interop tests (tests/interop/test_tcpcl4_interop.py):
# the RFC 9174 author's agent, github BrianSipos/dtn-demo-agent (package `tcpcl`), from a source tree.
#
#   scripts/setup_tcpcl4_peer.sh SRC_DIR [DEST]
#
# SRC_DIR  a dtn-demo-agent source tree (a clone or an exported snapshot; its src/tcpcl is used).
# DEST     default ~/.cache/constellation/tcpcl4-peer (the tests read $TCPCL4_PEER, else this):
#          DEST/src (a copy of SRC_DIR/src) and DEST/venv (Debian's python3 with its D-Bus, GLib,
#          cryptography and YAML packages, plus asn1 and scapy pinned from PyPI).
# Nothing of the agent enters this repository.
set -euo pipefail
src=${1:?usage: setup_tcpcl4_peer.sh SRC_DIR [DEST]}
dest=${2:-${TCPCL4_PEER:-$HOME/.cache/constellation/tcpcl4-peer}}
if [[ ! -d "$src/src/tcpcl" ]]; then
    echo "setup_tcpcl4_peer.sh: $src has no src/tcpcl (not a dtn-demo-agent tree)" >&2
    exit 2
fi
if [[ $(id -u) == 0 ]] && command -v apt-get >/dev/null; then
    apt-get install -y python3-venv python3-dbus python3-gi python3-cryptography python3-yaml dbus-daemon >/dev/null
fi
mkdir -p "$dest"
rm -rf "$dest/src" && cp -a "$src/src" "$dest/src"
/usr/bin/python3 -m venv --system-site-packages "$dest/venv"
"$dest/venv/bin/pip" install -q asn1==2.7.1 scapy==2.6.1
"$dest/venv/bin/python" -c "import sys; sys.path.insert(0, '$dest/src'); import tcpcl.agent" \
    || { echo "setup_tcpcl4_peer.sh: the agent does not import" >&2; exit 1; }
echo "TCPCLv4 peer ready in $dest"
