#!/usr/bin/env bash
# Set up what container runs and the `containers` tests need, on a Debian machine, as root:
#   podman + runc (OCI containers without a Docker engine), debootstrap (the base image from Debian
#   packages, for machines that reach no image registry), iptables + iproute2 (the network
#   impairment, bringup/deploy/impair.py), catatonit (the containers' init), util-linux (nsenter);
#   the project's .venv with podman-compose (pyproject extra 'containers');
#   then, unless --packages-only, the images: `constellation containers build` (base image
#   localhost/agile-dtn-base:bookworm when missing, then localhost/agile-dtn-constellation:0.1.0).
# Idempotent. The tests build their own run-unique images, so CI calls it with --packages-only.
set -euo pipefail
cd "$(dirname "$0")/.."
packages_only=0
for a in "$@"; do
    case "$a" in
        --packages-only) packages_only=1 ;;
        *) echo "setup_containers: unknown option $a (use --packages-only)" >&2; exit 2 ;;
    esac
done
bash scripts/setup.sh
need=(podman runc debootstrap iptables iproute2 catatonit util-linux)
missing=()
for p in "${need[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ "${#missing[@]}" -gt 0 ]; then
    if [ "$(id -u)" -ne 0 ]; then
        echo "setup_containers: installing ${missing[*]} needs root (apt-get)" >&2; exit 1
    fi
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -q
    apt-get install -y -q "${missing[@]}"
fi
stamp=.venv/.containers-$(sha256sum pyproject.toml | cut -c1-16)
if [ ! -f "$stamp" ]; then
    .venv/bin/python -m pip install --quiet -e '.[dev,containers]'
    rm -f .venv/.containers-*
    touch "$stamp"
fi
if [ "$packages_only" -eq 0 ]; then
    .venv/bin/constellation containers build
fi
