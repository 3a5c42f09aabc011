#!/usr/bin/env bash
# Build ION-DTN (NASA JPL's DTN stack) from a source tree, for the interop tests
# (tests/interop/, marker `interop`; docs/guide/dtn-interop.md).
#
#   scripts/build_ion.sh SRC_DIR [PREFIX]
#
# SRC_DIR  an ION-DTN source tree (a clone or an exported snapshot of github nasa-jpl/ION-DTN,
#          e.g. `git -C ION-DTN archive ion-open-source-4.1.3 | tar -x -C /tmp/ion-src`).
#          Without one, set ION_GIT_URL to clone where the network allows.
# PREFIX   where to install (default: $HOME/.cache/constellation/ion); the tests look there, or at
#          $ION_PREFIX.
#
# The build is out of the repository (nothing of ION is committed), runs at nice 19 with one make job
# by default (ION_JOBS to change), and needs autoconf, automake and libtool (Debian packages; installed
# here when missing and running as root). About 25 min on 2 cores.
set -euo pipefail

src=${1:-}
prefix=${2:-${ION_PREFIX:-$HOME/.cache/constellation/ion}}
jobs=${ION_JOBS:-1}

if [[ -z "$src" ]]; then
    if [[ -n "${ION_GIT_URL:-}" ]]; then
        src=$(mktemp -d)/ion-src
        git clone --depth 1 --branch "${ION_GIT_REF:-ion-open-source-4.1.3}" "$ION_GIT_URL" "$src"
    else
        echo "build_ion.sh: give an ION-DTN source tree (or set ION_GIT_URL)" >&2
        exit 2
    fi
fi
if [[ ! -f "$src/configure.ac" || ! -d "$src/bpv7" ]]; then
    echo "build_ion.sh: $src is not an ION-DTN source tree (no configure.ac or bpv7/)" >&2
    exit 2
fi
for tool in autoreconf libtoolize make gcc; do
    if ! command -v "$tool" >/dev/null; then
        if [[ $(id -u) == 0 ]] && command -v apt-get >/dev/null; then
            apt-get install -y autoconf automake libtool make gcc >/dev/null
        else
            echo "build_ion.sh: $tool missing (Debian: apt-get install autoconf automake libtool)" >&2
            exit 2
        fi
    fi
done

build=$(mktemp -d "${TMPDIR:-/tmp}/ion-build.XXXXXX")
cp -a "$src/." "$build/"
cd "$build"
if [[ ! -x configure ]]; then
    nice -n 19 autoreconf -fi >autoreconf.log 2>&1 || { tail -20 autoreconf.log >&2; exit 1; }
fi
# BPv7 only (ION's default is bpv7 since 4.0); no manual pages.
nice -n 19 ./configure --prefix="$prefix" --disable-dependency-tracking >configure.log 2>&1 \
    || { tail -20 configure.log >&2; exit 1; }
# A source snapshot may lack ION's large binary documents (stored outside git); only the
# documentation targets need them: an empty stand-in lets the build and install go on.
for doc in ION-LTP-configuration.pdf; do
    [[ -e "$doc" ]] || : >"$doc"
done
nice -n 19 make -j"$jobs" >make.log 2>&1 || { tail -30 make.log >&2; exit 1; }
nice -n 19 make install >install.log 2>&1 || { tail -20 install.log >&2; exit 1; }
echo "ION installed in $prefix (build tree $build)"
"$prefix/bin/bpversion" 2>/dev/null || true
