#!/usr/bin/env bash
# The README's test command: installs what is missing, builds, runs every test.
# Then a second tree with AddressSanitizer + UndefinedBehaviorSanitizer
# (LMF_SANITIZE=ON, benchmarks off) in BUILD_DIR_ASAN (default build-asan):
# every test except those that start the real binaries in network namespaces
# (System.*, NetworkSandbox.*, PlayerAgentProcesses.*), i.e. the unit tests,
# the in-process node tests over memq:// and the short fuzz runs (label fuzz).
# ASAN_CTEST_EXCLUDE replaces that exclusion regex; SANITIZE=0 skips the second tree.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
"$root/scripts/install-deps.sh"
"$root/scripts/build.sh"
cd "${BUILD_DIR:-$root/build}"
ctest --output-on-failure -j "${JOBS:-$(nproc)}" --timeout 600

if [[ "${SANITIZE:-1}" != 0 ]]; then
  asan_dir=${BUILD_DIR_ASAN:-$root/build-asan}
  echo "== ASan+UBSan build in $asan_dir"
  BUILD_DIR=$asan_dir "$root/scripts/build.sh" -DLMF_SANITIZE=ON -DLMF_BUILD_BENCHMARKS=OFF
  cd "$asan_dir"
  ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1} \
  UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1} \
    ctest --output-on-failure -j "${JOBS:-$(nproc)}" --timeout 900 \
      -E "${ASAN_CTEST_EXCLUDE:-^(System|NetworkSandbox|PlayerAgentProcesses)\.}"
fi
