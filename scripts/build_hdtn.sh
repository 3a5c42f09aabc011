#!/usr/bin/env bash
# Build HDTN (NASA Glenn's High-rate Delay Tolerant Networking, C++, speaks TCPCLv4 / RFC 9174) from a
# source tree, for the interop tests (tests/interop/, marker `interop`; docs/guide/dtn-interop.md).
#
#   scripts/build_hdtn.sh SRC_DIR [PREFIX]
#
# SRC_DIR  an HDTN source tree (a clone or an exported snapshot of github nasa/HDTN, e.g.
#          `git -C HDTN archive v1.3.1 | tar -x -C /tmp/hdtn-src`; a snapshot that lacks a large
#          contact plan's blob exports with `git archive HEAD -- . ':(exclude)PATH'`, nothing built needs it).
#          Without one, set HDTN_GIT_URL to clone where the network allows (HDTN_GIT_REF: tag or branch).
# PREFIX   where to install (default: $HOME/.cache/constellation/hdtn); the tests look there, or at
#          $HDTN_PREFIX.
#
# The build is out of the repository and of the source tree (HDTN's CMake only adds empty logs/ and
# stats/ folders to it), runs at nice 19 (HDTN_NICE to change) with HDTN_JOBS make jobs (default 1),
# and needs CMake, a C++ compiler, Boost >= 1.66 (the components HDTN's CMakeLists.txt asks for),
# ZeroMQ and OpenSSL: the Debian packages are installed here when missing and running as root. Only
# what the tests use is built and installed: the node (hdtn-one-process) and the bundle apps
# bpgen-async and bpsink-async (HDTN_TARGETS to change), with HDTN's own config files in
# PREFIX/share/HDTN/config_files. Off: the web interface (it would download CivetWeb or pull
# Boost.Beast), BPSec, stats logging, video streaming. LTP, STCP and UDP stay in: HDTN's induct and
# outduct managers link them unconditionally. An interrupted build goes on where it stopped with
# HDTN_BUILD_DIR=<its build folder>.
set -euo pipefail

src=${1:-}
prefix=${2:-${HDTN_PREFIX:-$HOME/.cache/constellation/hdtn}}
jobs=${HDTN_JOBS:-1}
niceness=${HDTN_NICE:-19}
read -r -a targets <<<"${HDTN_TARGETS:-hdtn-one-process bpgen-async bpsink-async}"

if [[ -z "$src" ]]; then
    if [[ -n "${HDTN_GIT_URL:-}" ]]; then
        src=$(mktemp -d)/hdtn-src
        git clone --depth 1 --branch "${HDTN_GIT_REF:-master}" "$HDTN_GIT_URL" "$src"
    else
        echo "build_hdtn.sh: give an HDTN source tree (or set HDTN_GIT_URL)" >&2
        exit 2
    fi
fi
if [[ ! -f "$src/CMakeLists.txt" || ! -d "$src/module/hdtn_one_process" || ! -d "$src/common/tcpcl" ]]; then
    echo "build_hdtn.sh: $src is not an HDTN source tree (no CMakeLists.txt, module/hdtn_one_process" \
        "or common/tcpcl)" >&2
    exit 2
fi
src=$(cd "$src" && pwd)

debs=(cmake make g++ pkg-config libzmq3-dev libssl-dev libboost-dev libboost-system-dev
    libboost-date-time-dev libboost-filesystem-dev libboost-timer-dev libboost-thread-dev
    libboost-regex-dev libboost-program-options-dev libboost-test-dev libboost-iostreams-dev
    libboost-random-dev libboost-log-dev)
missing=()
if command -v dpkg-query >/dev/null; then
    for deb in "${debs[@]}"; do
        dpkg-query -W -f='${Status}' "$deb" 2>/dev/null | grep -q "install ok installed" || missing+=("$deb")
    done
fi
if ((${#missing[@]})); then
    if [[ $(id -u) == 0 ]] && command -v apt-get >/dev/null; then
        DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends "${missing[@]}" >/dev/null
    else
        echo "build_hdtn.sh: missing Debian packages: ${missing[*]} (apt-get install them, as root)" >&2
        exit 2
    fi
fi
for tool in cmake make g++; do
    command -v "$tool" >/dev/null || { echo "build_hdtn.sh: $tool missing" >&2; exit 2; }
done

# HDTN_BUILD_DIR: a build folder of an earlier run to go on with (make rebuilds only what is missing)
build=${HDTN_BUILD_DIR:-$(mktemp -d "${TMPDIR:-/tmp}/hdtn-build.XXXXXX")}
mkdir -p "$build"
cd "$build"
start=$(date +%s)
nice -n "$niceness" cmake "$src" -DCMAKE_BUILD_TYPE=Release -DCMAKE_INSTALL_PREFIX="$prefix" \
    -DUSE_WEB_INTERFACE:BOOL=OFF -DENABLE_BPSEC:BOOL=OFF -DENABLE_OPENSSL_SUPPORT:BOOL=ON \
    -DDO_STATS_LOGGING:BOOL=OFF -DENABLE_STREAMING_SUPPORT:BOOL=OFF -DLOG_LEVEL_TYPE=INFO \
    >cmake.log 2>&1 || { tail -30 cmake.log >&2; exit 1; }
nice -n "$niceness" make -j"$jobs" "${targets[@]}" >make.log 2>&1 \
    || { grep -m5 -B2 -A8 "error" make.log >&2 || tail -30 make.log >&2; exit 1; }
mkdir -p "$prefix/bin" "$prefix/share/HDTN"
for target in "${targets[@]}"; do
    exe=$(find "$build" -type f -name "$target" -perm -u+x | head -1)
    [[ -n "$exe" ]] || { echo "build_hdtn.sh: $target was not built (see $build/make.log)" >&2; exit 1; }
    install -m 0755 "$exe" "$prefix/bin/$target"
done
rm -rf "$prefix/share/HDTN/config_files"
cp -a "$src/config_files" "$prefix/share/HDTN/config_files"
# Which HDTN this is: the source's version file or git description, kept next to the binaries.
{
    echo "source: $src"
    git -C "$src" describe --tags --always 2>/dev/null || true
    grep -m1 -E "^## *\[?v?[0-9]" "$src/CHANGELOG.md" 2>/dev/null || true
    echo "built: $(date -u +%FT%TZ) in $(($(date +%s) - start)) s with $jobs job(s)"
} >"$prefix/share/HDTN/BUILD_INFO"
echo "HDTN installed in $prefix (build tree $build; $(($(date +%s) - start)) s)"
