#!/usr/bin/env bash
# Soak run: a long simulated mission through the real processes (lmf-server,
# one lmf-agent per robot, lmf-player, lmf-monitor, lcm-logger) inside a private
# network namespace, sampling every process's resident memory and CPU time.
#
#   scripts/soak.sh [--robots 8] [--duration-s 3600] [--seed 4] [--lockstep | --rate R]
#                   [--loss P] [--sample-s 1] [--build DIR] [--out DIR]
#
# Writes into --out (default soak-out/): soak.json (the summary below),
# soak.svg (RSS and CPU per process over time), samples.txt (the raw samples),
# the mission's outputs and every process's log. Checks, and exits 1 if one fails:
#   * every local map each agent shipped was acknowledged (the agents' logs);
#   * lockstep without loss: the trajectories equal lmf-offline's on the same
#     input within 1 cm (under loss the fusion order, hence the map, may change:
#     docs/reliability.md, so this is then reported, not checked);
#   * missions of 10 min or more: each process's RSS grows by less than 10 %
#     over the second half of the run (after warm-up; shorter runs report it).
# --loss P makes the server, agents and player each lose P of what they
# publish (--simulate-loss): no iptables needed.
# Exit 77 when no private network namespace can be made here.
set -euo pipefail
src=$(cd "$(dirname "$0")/.." && pwd)
robots=8 duration=3600 seed=4 mode=(--lockstep) loss="" sample_s=1 build="$src/build" out=soak-out
while [[ $# -gt 0 ]]; do
  case $1 in
    --robots) robots=$2; shift 2 ;;
    --duration-s) duration=$2; shift 2 ;;
    --seed) seed=$2; shift 2 ;;
    --lockstep) mode=(--lockstep); shift ;;
    --rate) mode=(--rate "$2"); shift 2 ;;
    --loss) loss=$2; shift 2 ;;
    --sample-s) sample_s=$2; shift 2 ;;
    --build) build=$2; shift 2 ;;
    --out) out=$2; shift 2 ;;
    -h|--help) sed -n '2,21p' "$0"; exit 0 ;;
    *) echo "soak.sh: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
done
source "$src/scripts/lib/netns.sh"
if ! lmf_netns_supported; then echo "SKIP: cannot create a private network namespace here"; exit 77; fi
for b in tools/lmf-sim tools/lmf-offline tools/lmf-score fusion_server/lmf-server robot_agent/lmf-agent \
         log_player/lmf-player monitor/lmf-monitor; do
  [[ -x $build/$b ]] || { echo "soak.sh: $build/$b not built (scripts/build.sh)" >&2; exit 2; }
done
command -v lcm-logger >/dev/null || { echo "soak.sh: lcm-logger not found (liblcm-bin)" >&2; exit 2; }

mkdir -p "$out"
out=$(cd "$out" && pwd)
rm -rf "$out/sim" "$out/offline" "$out/mission" "$out/samples.txt"
config=$src/config/sim.json
echo "soak: $robots robots, ${duration} s, seed $seed, player ${mode[*]}${loss:+, $loss loss on every link}"
"$build/tools/lmf-sim" --robots "$robots" --seed "$seed" --duration-s "$duration" --out "$out/sim" >/dev/null
equal_check=0
if [[ ${mode[0]} == --lockstep && -z $loss ]]; then
  equal_check=1
  "$build/tools/lmf-offline" --sim "$out/sim" --config "$config" --out "$out/offline" >"$out/offline.log" 2>&1
fi

start=$(date +%s)
rc=0
LMF_SAMPLE_FILE="$out/samples.txt" LMF_SAMPLE_S=$sample_s LMF_SIMULATE_LOSS=$loss LMF_SETTLE_S=5 \
  lmf_netns_exec bash "$src/scripts/lib/run-mission.sh" "$build" "$out/sim" "$out/mission" "$robots" "$config" \
  "${mode[@]}" --quiet >"$out/run.log" 2>&1 || rc=$?
wall=$(( $(date +%s) - start ))
cat "$out/run.log"
[[ $rc -eq 0 ]] || echo "soak: the mission exited with $rc"

trajectories=()
if [[ $equal_check -eq 1 ]]; then
  for ((r = 0; r < robots; ++r)); do
    trajectories+=(--est "$out/mission/trajectories/robot$r.txt" --ref "$out/offline/trajectories/robot$r.txt")
  done
  "$build/tools/lmf-score" --json --no-align "${trajectories[@]}" >"$out/vs-offline.json" || rc=1
fi

python3 "$src/scripts/lib/soak_summary.py" --out "$out" --robots "$robots" --duration-s "$duration" \
  --wall-s "$wall" --mode="${mode[*]}" --loss "${loss:-0}" --equal-check "$equal_check" \
  --clock-ticks "$(getconf CLK_TCK)" || rc=1
exit $rc
