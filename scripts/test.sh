#!/usr/bin/env bash
# The README's test command: installs what is missing, builds, runs every test.
# Then a second tree with AddressSanitizer + UndefinedBehaviorSanitizer
# (LMF_SANITIZE=ON, benchmarks off) in BUILD_DIR_ASAN (default build-asan):
# every test except those that start the real binaries in network namespaces
# (System.*, NetworkSandbox.*, PlayerAgentProcesses.*), i.e. the unit tests,
# the in-process node tests over memq:// and the short fuzz runs (label fuzz).
# ASAN_CTEST_EXCLUDE replaces that exclusion regex; SANITIZE=0 skips the second tree.
# Both builds go through ccache where it is installed (scripts/build.sh), so a
# clone in another folder reuses what an earlier build compiled.
# Prints how long each phase took, and a summary of all of them at the end.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)

phases=()
phase_start=0
begin() { echo "== $1"; phase_name=$1; phase_start=$(date +%s.%N); }
end() {
  local s
  s=$(awk -v a="$phase_start" -v b="$(date +%s.%N)" 'BEGIN { printf "%.0f", b - a }')
  phases+=("$(printf '%-18s %5d s' "$phase_name" "$s")")
  echo "== $phase_name: ${s} s"
}
summary() {
  echo "== phase times"
  for p in "${phases[@]}"; do echo "   $p"; done
  # Disk: what the build trees take and what is left (a full disk fails a link).
  echo "== disk"
  for d in "${BUILD_DIR:-$root/build}" "${BUILD_DIR_ASAN:-$root/build-asan}"; do
    [[ -d $d ]] && du -sh "$d" 2>/dev/null | sed 's/^/   /'
  done
  df -h "$root" 2>/dev/null | awk 'NR == 2 { print "   free: " $4 " of " $2 }'
}
trap summary EXIT

begin "install check"
"$root/scripts/install-deps.sh"
end

begin "build"
"$root/scripts/build.sh"
end

begin "tests"
cd "${BUILD_DIR:-$root/build}"
ctest --output-on-failure -j "${JOBS:-$(nproc)}" --timeout 600
end

if [[ "${SANITIZE:-1}" != 0 ]]; then
  asan_dir=${BUILD_DIR_ASAN:-$root/build-asan}
  begin "sanitizer build"
  echo "   (ASan+UBSan tree in $asan_dir)"
  BUILD_DIR=$asan_dir "$root/scripts/build.sh" -DLMF_SANITIZE=ON -DLMF_BUILD_BENCHMARKS=OFF
  end
  begin "sanitizer tests"
  cd "$asan_dir"
  ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1} \
  UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1} \
    ctest --output-on-failure -j "${JOBS:-$(nproc)}" --timeout 900 \
      -E "${ASAN_CTEST_EXCLUDE:-^(System|NetworkSandbox|PlayerAgentProcesses)\.}"
  end
fi
