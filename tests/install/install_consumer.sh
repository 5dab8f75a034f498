#!/usr/bin/env bash
# `cmake --install` of the Development component into a scratch prefix, then a
# project outside lmf (consumer/) configured with find_package(lmf), built and
# run against it; the installed CMake package must not point back into the
# source or build tree.
#   install_consumer.sh BUILD_DIR CONSUMER_SOURCE_DIR CXX_COMPILER
set -euo pipefail
build=$1 consumer=$2 cxx=$3
work=$(mktemp -d)
[[ -n ${LMF_TEST_KEEP:-} ]] && echo "keeping $work" || trap 'rm -rf "$work"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }
prefix=$work/prefix

cmake --install "$build" --prefix "$prefix" --component Development >"$work/install.log"
for f in lib/cmake/lmf/lmfConfig.cmake lib/cmake/lmf/lmfConfigVersion.cmake lib/cmake/lmf/lmfTargets.cmake \
         lib/liblmf_geometry.a lib/liblmf_local_map.a include/lmf/geometry/pose2.hpp \
         include/lmf/local_map/local_map.hpp include/lmf/scan/observed_segment.hpp include/lmf/pose2_t.hpp \
         share/lmf/lcmtypes/lmf_pose2_t.lcm; do
  [[ -f $prefix/$f ]] || fail "not installed: $f"
done
source_dir=$(cd "$(dirname "$0")/../.." && pwd)
if grep -rl -e "$source_dir" -e "$build" "$prefix/lib/cmake"; then fail "the installed package names the source or build tree"; fi

launcher=()
if command -v ccache >/dev/null && [[ -n ${CCACHE_DIR:-} ]]; then launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache); fi
cmake -S "$consumer" -B "$work/build" -DCMAKE_PREFIX_PATH="$prefix" -DCMAKE_CXX_COMPILER="$cxx" \
  -DCMAKE_BUILD_TYPE=Release "${launcher[@]}" >"$work/configure.log" 2>&1 ||
  { cat "$work/configure.log"; fail "configure against the installed lmf"; }
grep -q "lmf_DIR.*=$prefix/lib/cmake/lmf" "$work/build/CMakeCache.txt" || fail "lmf not found in the scratch prefix"
cmake --build "$work/build" -j 2 >"$work/build.log" 2>&1 || { cat "$work/build.log"; fail "build against the installed lmf"; }
for exe in lmf_consumer; do
  output=$("$work/build/$exe") || fail "$exe exited with $?: $output"
  echo "$exe: $output"
  grep -q "local map: 1 segments" <<<"$output" || fail "$exe: unexpected output"
done
echo "PASS: consumer built and ran against $prefix"
