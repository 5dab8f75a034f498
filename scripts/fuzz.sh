#!/usr/bin/env bash
# Long fuzz runs of every target in tests/fuzz under
# AddressSanitizer + UndefinedBehaviorSanitizer, with a summary table.
#   scripts/fuzz.sh [--runs N] [--seed S] [--targets "t1 t2"] [--libfuzzer]
# Default: the standalone driver lmf-fuzz from the sanitizer tree
# BUILD_DIR_ASAN (default build-asan, configured with LMF_SANITIZE=ON), the
# seeds plus N = 80000 mutated inputs per target: 14 targets, > 1,120,000
# inputs. JOBS targets run at once (default 1: the machine may be shared).
# --libfuzzer: clang-14 libFuzzer binaries instead (BUILD_DIR_LIBFUZZER,
# default build-libfuzzer, LMF_BUILD_FUZZERS=ON + LMF_SANITIZE=ON; needs
# scripts/install-deps.sh --fuzz), each started from the seed corpus that
# lmf-fuzz writes, for -runs=N.
# Logs and any crash-* input go to OUT (default <build dir>/fuzz-runs). Exits
# non-zero if any target crashed or reported.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
runs=80000
seed=1
targets=""
libfuzzer=0
while [[ $# -gt 0 ]]; do
  case $1 in
    --runs) runs=${2:?--runs needs a value}; shift 2 ;;
    --seed) seed=${2:?--seed needs a value}; shift 2 ;;
    --targets) targets=${2:?--targets needs a value}; shift 2 ;;
    --libfuzzer) libfuzzer=1; shift ;;
    *) echo "usage: scripts/fuzz.sh [--runs N] [--seed S] [--targets \"t1 t2\"] [--libfuzzer]" >&2; exit 2 ;;
  esac
done
jobs=${JOBS:-1}
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}

asan=${BUILD_DIR_ASAN:-$root/build-asan}
echo "== building lmf-fuzz with ASan+UBSan in $asan"
cmake -S "$root" -B "$asan" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DLMF_SANITIZE=ON \
  -DLMF_BUILD_BENCHMARKS=OFF >/dev/null
cmake --build "$asan" -j "${BUILD_JOBS:-$(nproc)}" --target lmf-fuzz
fuzz=$asan/tests/fuzz/lmf-fuzz
[[ -n $targets ]] || targets=$("$fuzz" --list | tr '\n' ' ')

build=$asan
if ((libfuzzer)); then
  "$root/scripts/install-deps.sh" --fuzz
  build=${BUILD_DIR_LIBFUZZER:-$root/build-libfuzzer}
  echo "== building the libFuzzer binaries with clang-14 in $build"
  CC=clang-14 CXX=clang++-14 cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DLMF_SANITIZE=ON -DLMF_BUILD_FUZZERS=ON -DLMF_BUILD_BENCHMARKS=OFF >/dev/null
  # shellcheck disable=SC2086
  cmake --build "$build" -j "${BUILD_JOBS:-$(nproc)}" --target $(printf 'lmf_fuzz_%s ' $targets)
fi
out=${OUT:-$build/fuzz-runs}
mkdir -p "$out"

run_target() {
  local t=$1 log=$out/$1.log
  if ((libfuzzer)); then
    "$fuzz" "$t" --write-seeds "$out/corpus-$t" >/dev/null
    (cd "$out" && "$build/tests/fuzz/lmf_fuzz_$t" -runs="$runs" -seed="$seed" -max_len=1048576 \
      -print_final_stats=1 "$out/corpus-$t") >"$log" 2>&1
  else
    (cd "$out" && "$fuzz" "$t" --runs "$runs" --seed "$seed") >"$log" 2>&1
  fi
}

echo "== fuzzing: ${runs} inputs per target, seed $seed, $jobs at a time; logs in $out"
start=$(date +%s.%N)
pids=()
names=()
for t in $targets; do
  run_target "$t" &
  pids+=($!)
  names+=("$t")
  while (($(jobs -rp | wc -l) >= jobs)); do wait -n || true; done
done
failed=0
for i in "${!pids[@]}"; do
  if ! wait "${pids[$i]}"; then
    echo "FAILED: ${names[$i]} (see $out/${names[$i]}.log)"
    failed=1
  fi
done
end=$(date +%s.%N)

total=0
printf '%-26s %10s %10s %12s\n' target inputs seconds inputs/s
for t in $targets; do
  log=$out/$t.log
  if ((libfuzzer)); then
    n=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
    s=$(sed -n 's/^Done \([0-9]*\) runs in \([0-9]*\) second.*/\2/p' "$log" | tail -1)
  else
    n=$(sed -n 's/^lmf-fuzz [^:]*: \([0-9]*\) inputs in \([0-9.e+-]*\) s.*/\1/p' "$log")
    s=$(sed -n 's/^lmf-fuzz [^:]*: \([0-9]*\) inputs in \([0-9.e+-]*\) s.*/\2/p' "$log")
  fi
  n=${n:-0}
  s=${s:-0}
  total=$((total + n))
  printf '%-26s %10s %10.1f %12.0f\n' "$t" "$n" "$s" "$(awk -v n="$n" -v s="$s" 'BEGIN { print (s > 0 ? n / s : 0) }')"
done
wall=$(awk -v a="$start" -v b="$end" 'BEGIN { printf "%.0f", b - a }')
echo "total: $total inputs in ${wall} s wall clock; crashes/sanitizer reports: $( ((failed)) && echo "SEE ABOVE" || echo 0)"
if grep -l -E 'ERROR: (AddressSanitizer|LeakSanitizer)|runtime error:|PROPERTY FAILED|CRASH' "$out"/*.log 2>/dev/null; then
  echo "sanitizer or property reports found in the logs above" >&2
  failed=1
fi
exit $failed
