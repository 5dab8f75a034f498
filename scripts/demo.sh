#!/usr/bin/env bash
# The README's main command: installs what is missing, builds, simulates the
# 3-robot mission on the built-in building and runs the mapping on it.
# Everything it writes goes to OUT (default: out/).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
out=${OUT:-$root/out}
"$root/scripts/install-deps.sh"
BUILD_DIR=${BUILD_DIR:-$root/build} "$root/scripts/build.sh" >/dev/null
bin=${BUILD_DIR:-$root/build}/tools

mkdir -p "$out"
echo "== simulating a 3-robot mission (seed 1) into $out/sim"
"$bin/lmf-sim" --robots 3 --seed 1 --out "$out/sim"
echo "== wrote:"
ls -l "$out/sim"
