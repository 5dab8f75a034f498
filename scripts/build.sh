#!/usr/bin/env bash
# Configures and builds lmf into BUILD_DIR (default: build/). Extra arguments go
# to cmake; TARGETS (space-separated) builds only those targets.
#
# Compiler cache: where ccache is installed (scripts/install-deps.sh installs
# it), every compile goes through it, set up so that another clone in another
# folder hits the same cache: CCACHE_BASEDIR is the source root (absolute paths
# under it are hashed as relative ones) and the compiler's working directory is
# not hashed (CCACHE_NOHASHDIR). The cache is ccache's usual per-user one
# (~/.cache/ccache) bounded to CCACHE_MAXSIZE (default 5G; ccache evicts the
# least recently used). LMF_CCACHE=0 builds without it.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build_dir=${BUILD_DIR:-$root/build}
jobs=${JOBS:-$(nproc)}

launcher=()
export CCACHE_BASEDIR=$root
export CCACHE_NOHASHDIR=1
export CCACHE_MAXSIZE=${CCACHE_MAXSIZE:-5G}
# (A ccache that cannot use its cache folder, e.g. without a home, is left out.)
if [[ "${LMF_CCACHE:-1}" != 0 ]] && command -v ccache >/dev/null && ccache --zero-stats >/dev/null 2>&1; then
  launcher=(-DCMAKE_C_COMPILER_LAUNCHER=ccache -DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
else
  # An earlier configure with the launcher keeps it in the cache: clear it.
  launcher=(-UCMAKE_C_COMPILER_LAUNCHER -UCMAKE_CXX_COMPILER_LAUNCHER)
fi
cmake -S "$root" -B "$build_dir" -G Ninja -DCMAKE_BUILD_TYPE="${BUILD_TYPE:-RelWithDebInfo}" "${launcher[@]}" "$@" \
  >/dev/null
targets=()
for t in ${TARGETS:-}; do targets+=(--target "$t"); done
cmake --build "$build_dir" -j "$jobs" "${targets[@]}"
if [[ ${#launcher[@]} -gt 0 && "${launcher[0]}" == -DCMAKE_C_COMPILER_LAUNCHER=ccache ]]; then
  # One line: how much of this build the cache served.
  ccache --print-stats 2>/dev/null | awk -F'\t' '
    $1 == "direct_cache_hit" || $1 == "preprocessed_cache_hit" { hit += $2 }
    $1 == "cache_miss" { miss = $2 }
    END { if (hit + miss > 0) printf "build: ccache served %d of %d compiles\n", hit, hit + miss }'
fi
