#!/usr/bin/env bash
# Runs the distributed mission inside the current (private) network namespace:
# lcm-logger, lmf-server, one lmf-agent per robot, lmf-monitor, then lmf-player
# on an lmf-sim folder. Stops every process it started. Used by scripts/demo.sh
# through lmf_netns_exec; not meant to run on a host network.
#   run-mission.sh BIN_DIR SIM_DIR OUT_DIR NUM_ROBOTS CONFIG PLAYER_MODE...
# With LMF_KEYS_DIR set (lmf-keygen's folder), every lmf process runs with
# --keys LMF_KEYS_DIR/<its principal>.keys: authenticated messages.
set -euo pipefail
bin=$1 sim=$2 out=$3 robots=$4 config=$5
shift 5
player_mode=("$@")

pids=()
cleanup() {
  for pid in "${pids[@]}"; do kill "$pid" 2>/dev/null || true; done
  wait 2>/dev/null || true
}
trap cleanup EXIT

stop() {  # SIGTERM one process and wait for it (bounded)
  local pid=$1
  kill -TERM "$pid" 2>/dev/null || return 0
  for _ in $(seq 100); do kill -0 "$pid" 2>/dev/null || { wait "$pid" 2>/dev/null || true; return 0; }; sleep 0.1; done
  kill -KILL "$pid" 2>/dev/null || true
}

key_args=()
keys_for() {  # sets key_args for one principal
  key_args=()
  if [[ -n ${LMF_KEYS_DIR:-} ]]; then key_args=(--keys "$LMF_KEYS_DIR/$1.keys"); fi
}

mkdir -p "$out/logs"
lcm-logger -q --force "$out/lmf.lcmlog" & logger=$!; pids+=($logger)
keys_for server
"$bin/fusion_server/lmf-server" --config "$config" --out "$out" "${key_args[@]}" >"$out/logs/server.log" 2>&1 &
server=$!; pids+=($server)
agents=()
for ((r = 0; r < robots; ++r)); do
  keys_for "robot$r"
  "$bin/robot_agent/lmf-agent" --config "$config" --robot-id "$r" "${key_args[@]}" >"$out/logs/agent$r.log" 2>&1 &
  agents+=($!); pids+=($!)
done
keys_for monitor
"$bin/monitor/lmf-monitor" --json --timing-svg "$out/timing.svg" "${key_args[@]}" >"$out/logs/monitor.jsonl" \
  2>"$out/logs/monitor.err" &
monitor=$!; pids+=($monitor)

start=$(date +%s%N)
keys_for player
"$bin/log_player/lmf-player" --config "$config" --sim "$sim" "${player_mode[@]}" --start-delay-ms 1000 "${key_args[@]}"
end=$(date +%s%N)
echo "replay took $(( (end - start) / 1000000 )) ms (wall clock)"

sleep 2  # agents ship their unfinished maps on mission end; let the server fuse them
for a in "${agents[@]}"; do stop "$a"; done
stop "$server"
stop "$monitor"
stop "$logger"
