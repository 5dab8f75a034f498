#!/usr/bin/env bash
# The accuracy table: every dataset case and the simulator missions through lmf-offline with the
# built-in default configuration (no --config), scored against their references, two cases at a
# time. Prints one table (lmf-accuracy) and optionally writes it as JSON and markdown.
#
#   scripts/accuracy.sh [--quick | --smoke] [--json FILE] [--markdown FILE] [--work DIR] [--jobs N]
#                       [--config FILE]
#
# Cases (datasets from ../shared/datasets relative to the repository, or LMF_DATASETS_DIR):
#   NAME-noisy / NAME-realodo for belgioioso, freiburg-101, orebro, acapulco, infinite-corridor,
#   each with --split 1, 2, 3;
#   sim-3r-20min       lmf-sim --robots 3 --seed 1 --duration-s 1200
#   sim-8r-1h          lmf-sim --robots 8 --seed 4 --duration-s 3600
#   sim-3r-20min-real  lmf-sim --robots 3 --seed 1 --duration-s 1200 --odometry real
#   sim-3r-20min-short the same with a short-range sparse laser (--max-range-m 8 --beams 181)
# --quick: one run per building (realodo, the harder odometry, one robot) and sim-3r-20min:
#   a few minutes on 2 cores; the full run stays the reference.
# --smoke: only belgioioso-noisy split 1 and a 2-minute 3-robot real-odometry sim mission.
# Without the datasets folder the dataset cases are skipped with a message.
# --config FILE: every lmf-offline run reads FILE (a change measured on every case; the table
#   of record is the one without).
# Binaries come from BUILD_DIR (default build/); scripts/build.sh runs only if one is missing.
# Each case's outputs stay in the work folder (a temporary one, removed, unless --work).
# Exit status: 0 when every case ran and was scored, 1 otherwise, 2 for a usage error.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${BUILD_DIR:-$root/build}
datasets=${LMF_DATASETS_DIR:-$root/../shared/datasets}
smoke=0 quick=0 json_out="" markdown_out="" work="" jobs=2 config=""

usage() { sed -n '2,21p' "$0" | sed 's/^# \{0,1\}//'; }
while [[ $# -gt 0 ]]; do
  case "$1" in
    --smoke) smoke=1 ;;
    --quick) quick=1 ;;
    --json) json_out=${2:?--json needs a file}; shift ;;
    --markdown) markdown_out=${2:?--markdown needs a file}; shift ;;
    --work) work=${2:?--work needs a folder}; shift ;;
    --jobs) jobs=${2:?--jobs needs a number}; shift ;;
    --config) config=${2:?--config needs a file}; shift ;;
    -h|--help) usage; exit 0 ;;
    *) echo "accuracy.sh: unknown argument $1 (see --help)" >&2; exit 2 ;;
  esac
  shift
done
[[ $smoke == 1 && $quick == 1 ]] && { echo "accuracy.sh: --quick and --smoke exclude each other" >&2; exit 2; }
[[ "$jobs" =~ ^[1-9][0-9]*$ ]] || { echo "accuracy.sh: --jobs wants a positive integer" >&2; exit 2; }
# Output paths are used after a cd-free run, but make them absolute anyway.
abs() { [[ -z "$1" || "$1" == /* ]] && echo "$1" || echo "$PWD/$1"; }
json_out=$(abs "$json_out"); markdown_out=$(abs "$markdown_out"); config=$(abs "$config")
[[ -z "$config" || -f "$config" ]] || { echo "accuracy.sh: no config file $config" >&2; exit 2; }

tools=(lmf-offline lmf-sim lmf-accuracy)
for t in "${tools[@]}"; do
  if [[ ! -x "$build/tools/$t" ]]; then
    echo "accuracy.sh: $build/tools/$t is missing: building with scripts/build.sh" >&2
    BUILD_DIR=$build "$root/scripts/build.sh"
    break
  fi
done

if [[ -z "$work" ]]; then
  work=$(mktemp -d "${TMPDIR:-/tmp}/lmf-accuracy.XXXXXX")
  trap 'rm -rf "$work"' EXIT
else
  mkdir -p "$work"
  work=$(cd "$work" && pwd)
fi

# The cases, in table order: NAME and the command that fills the case folder $dir.
names=()
commands=()
add_case() { names+=("$1"); commands+=("$2"); }

offline="$build/tools/lmf-offline"
config_option=""  # spliced into each case's lmf-offline command
[[ -n "$config" ]] && config_option=" --config \"$config\""
sim="$build/tools/lmf-sim"
dataset_case() {  # NAME KIND SPLIT
  add_case "$1-$2-split$3" \
    "\"$offline\"$config_option --log \"$datasets/$1-$2.log.gz\" --split $3 --gt \"$datasets/$1-$2.gt\" --out \"\$dir\""
}
sim_case() {  # NAME lmf-sim-arguments
  add_case "$1" "\"$sim\" $2 --out \"\$dir/mission\" >\"\$dir/sim.txt\" && \"$offline\"$config_option --sim \"\$dir/mission\" --out \"\$dir\""
}

if [[ -d "$datasets" ]]; then
  buildings=(belgioioso freiburg-101 orebro acapulco infinite-corridor)
  if [[ $smoke == 1 ]]; then
    dataset_case belgioioso noisy 1
  elif [[ $quick == 1 ]]; then
    for name in "${buildings[@]}"; do dataset_case "$name" realodo 1; done
  else
    for kind in noisy realodo; do
      for name in "${buildings[@]}"; do
        for split in 1 2 3; do dataset_case "$name" "$kind" "$split"; done
      done
    done
  fi
else
  echo "accuracy.sh: SKIPPING the dataset cases: $datasets is absent (set LMF_DATASETS_DIR)" >&2
fi
if [[ $smoke == 1 ]]; then
  sim_case sim-3r-2min-real "--robots 3 --seed 1 --duration-s 120 --odometry real"
elif [[ $quick == 1 ]]; then
  sim_case sim-3r-20min "--robots 3 --seed 1 --duration-s 1200"
else
  sim_case sim-3r-20min "--robots 3 --seed 1 --duration-s 1200"
  sim_case sim-8r-1h "--robots 8 --seed 4 --duration-s 3600"
  sim_case sim-3r-20min-real "--robots 3 --seed 1 --duration-s 1200 --odometry real"
  sim_case sim-3r-20min-short "--robots 3 --seed 1 --duration-s 1200 --odometry real --max-range-m 8 --beams 181"
fi

# One case: its command under bash's `time` (wall, user, sys seconds into time.txt).
run_case() {
  local name=$1 command=$2
  local dir="$work/$name"
  rm -rf "$dir"
  mkdir -p "$dir"
  local status=0
  TIMEFORMAT='%R %U %S'
  # The inner group keeps the command's own output away from time's report.
  { time { (eval "$command") >"$dir/stdout.txt" 2>"$dir/stderr.txt"; }; } 2>"$dir/time.txt" || status=$?
  if [[ $status == 0 ]]; then
    echo "accuracy.sh: $name done in $(cut -d' ' -f1 "$dir/time.txt") s" >&2
  else
    echo "accuracy.sh: $name FAILED (exit $status): $(tail -n 3 "$dir/stderr.txt")" >&2
  fi
}

# Longest cases first keeps both cores busy to the end; the table keeps the listed order.
order=()
for i in "${!names[@]}"; do [[ ${names[$i]} == sim-* ]] && order+=("$i"); done
for i in "${!names[@]}"; do [[ ${names[$i]} != sim-* ]] && order+=("$i"); done

start=$(date +%s.%N)
running=0
for i in "${order[@]}"; do
  if (( running >= jobs )); then
    wait -n || true
    running=$((running - 1))
  fi
  run_case "${names[$i]}" "${commands[$i]}" &
  running=$((running + 1))
done
wait
total=$(awk -v s="$start" -v e="$(date +%s.%N)" 'BEGIN { printf "%.1f", e - s }')

case_args=()
for name in "${names[@]}"; do case_args+=(--case "$name=$work/$name"); done
report_args=(--total-wall-s "$total"
             --note "lmf-offline with ${config:-the built-in default configuration (no --config)}; $jobs cases at a time"
             --note "commit $(git -C "$root" rev-parse --short HEAD 2>/dev/null || echo unknown)$(git -C "$root" diff --quiet 2>/dev/null || echo ' (with local changes)')")
[[ -n "$json_out" ]] && report_args+=(--json "$json_out")
[[ -n "$markdown_out" ]] && report_args+=(--markdown "$markdown_out")
status=0
"$build/tools/lmf-accuracy" "${case_args[@]}" "${report_args[@]}" || status=$?
printf 'accuracy.sh: %d cases, %.0f s wall in total\n' "${#names[@]}" "$total" >&2
exit $status
