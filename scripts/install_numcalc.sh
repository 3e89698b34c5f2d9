#!/usr/bin/env bash
# Build Mesh2HRTF's NumCalc from a Mesh2HRTF checkout or release folder you downloaded (1.2.x) with that
# checkout's own Makefile, and install the binary as .venv/bin/NumCalc, where the pipeline finds it.
# The sources are built in a temporary copy: your checkout is left untouched and nothing of it enters
# this repository. NUMCALC_PREFIX=DIR installs into DIR instead of .venv/bin.
#
#   bash scripts/install_numcalc.sh /path/to/Mesh2HRTF
set -euo pipefail
cd "$(dirname "$0")/.."
if [ $# -ne 1 ]; then
    echo "usage: bash scripts/install_numcalc.sh MESH2HRTF_DIR  (a Mesh2HRTF 1.2.x checkout or release folder)" >&2
    exit 2
fi
M2H="$1"
SRC=""
for candidate in "$M2H/mesh2hrtf/NumCalc/src" "$M2H/NumCalc/src" "$M2H/src"; do
    if [ -f "$candidate/Makefile" ] && [ -f "$candidate/NC_Main.cpp" ]; then SRC="$candidate"; break; fi
done
if [ -z "$SRC" ]; then
    echo "error: $M2H holds no NumCalc sources (looked for mesh2hrtf/NumCalc/src/Makefile and NC_Main.cpp)." >&2
    echo "Get Mesh2HRTF 1.2.x (git clone of the Mesh2HRTF repository, tag v1.2.4) and pass its top folder." >&2
    exit 2
fi
command -v make >/dev/null || { echo "error: 'make' is missing (Debian: apt-get install make)" >&2; exit 2; }
command -v g++ >/dev/null || { echo "error: 'g++' is missing (Debian: apt-get install g++)" >&2; exit 2; }
PREFIX="${NUMCALC_PREFIX:-.venv/bin}"
[ -x .venv/bin/python ] || bash scripts/setup.sh
mkdir -p "$PREFIX"
BUILD="$(mktemp -d)"
trap 'rm -rf "$BUILD"' EXIT
mkdir -p "$BUILD/src" "$BUILD/bin"
cp -R "$SRC"/. "$BUILD/src/"
rm -f "$BUILD"/src/*.o
echo "building NumCalc from $SRC (its Makefile, in $BUILD) ..."
make -C "$BUILD/src" -j "$(nproc)" >"$BUILD/build.log" 2>&1 || { tail -30 "$BUILD/build.log" >&2; echo "error: the build failed" >&2; exit 1; }
[ -x "$BUILD/bin/NumCalc" ] || { echo "error: the Makefile did not produce bin/NumCalc" >&2; exit 1; }
install -m 755 "$BUILD/bin/NumCalc" "$PREFIX/NumCalc.partial"
mv "$PREFIX/NumCalc.partial" "$PREFIX/NumCalc"
echo "installed $PREFIX/NumCalc"
.venv/bin/m2h doctor --numcalc "$PREFIX/NumCalc"
