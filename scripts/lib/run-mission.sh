#!/usr/bin/env bash
# Runs the distributed mission inside the current (private) network namespace:
# lcm-logger, lmf-server, one lmf-agent per robot, lmf-monitor, then lmf-player
# on an lmf-sim folder. Stops every process it started. Used by scripts/demo.sh
# through lmf_netns_exec; not meant to run on a host network.
#   run-mission.sh BIN_DIR SIM_DIR OUT_DIR NUM_ROBOTS CONFIG PLAYER_MODE...
# With LMF_KEYS_DIR set (lmf-keygen's folder), every lmf process runs with
# --keys LMF_KEYS_DIR/<its principal>.keys: authenticated messages.
# With LMF_SIMULATE_LOSS=P the server, the agents and the player each lose P
# of what they publish (--simulate-loss, a seed per process).
# With LMF_SAMPLE_FILE=F every process's resident memory and CPU time are
# appended to F every LMF_SAMPLE_S seconds (1) as lines
#   <ms since start> <process> <pid> <VmRSS kB> <utime+stime clock ticks>
# LMF_SETTLE_S (2): seconds between the player's end and stopping the others.
set -euo pipefail
bin=$1 sim=$2 out=$3 robots=$4 config=$5
shift 5
player_mode=("$@")

pids=()
cleanup() {
  for pid in "${pids[@]}" ${sampler:-}; do kill "$pid" 2>/dev/null || true; done
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

loss_args=()
loss_for() {  # sets loss_args for one process, seeded by its index
  loss_args=()
  if [[ -n ${LMF_SIMULATE_LOSS:-} ]]; then loss_args=(--simulate-loss "$LMF_SIMULATE_LOSS" --simulate-seed "$1"); fi
}

names=()  # parallel to pids, for the sampler
sample() {  # runs in the background until killed
  local t0 name pid rss ticks stat
  t0=$(date +%s%N)
  while true; do
    for i in "${!pids[@]}"; do
      pid=${pids[$i]} name=${names[$i]}
      [[ -r /proc/$pid/status ]] || continue
      rss=$(awk '/^VmRSS:/ {print $2}' "/proc/$pid/status" 2>/dev/null) || continue
      stat=$(cat "/proc/$pid/stat" 2>/dev/null) || continue
      stat=${stat##*) }  # fields after the command name; utime and stime are the 12th and 13th
      ticks=$(awk '{print $12 + $13}' <<<"$stat")
      echo "$(( ($(date +%s%N) - t0) / 1000000 )) $name $pid ${rss:-0} $ticks"
    done >>"$LMF_SAMPLE_FILE"
    sleep "${LMF_SAMPLE_S:-1}"
  done
}

mkdir -p "$out/logs"
lcm-logger -q --force "$out/lmf.lcmlog" & logger=$!; pids+=($logger); names+=(lcm-logger)
keys_for server
loss_for 1
"$bin/fusion_server/lmf-server" --config "$config" --out "$out" "${key_args[@]}" "${loss_args[@]}" \
  >"$out/logs/server.log" 2>&1 &
server=$!; pids+=($server); names+=(lmf-server)
agents=()
for ((r = 0; r < robots; ++r)); do
  keys_for "robot$r"
  loss_for $((r + 2))
  "$bin/robot_agent/lmf-agent" --config "$config" --robot-id "$r" "${key_args[@]}" "${loss_args[@]}" \
    >"$out/logs/agent$r.log" 2>&1 &
  agents+=($!); pids+=($!); names+=("lmf-agent$r")
done
keys_for monitor
"$bin/monitor/lmf-monitor" --json --timing-svg "$out/timing.svg" "${key_args[@]}" >"$out/logs/monitor.jsonl" \
  2>"$out/logs/monitor.err" &
monitor=$!; pids+=($monitor); names+=(lmf-monitor)

start=$(date +%s%N)
keys_for player
loss_for $((robots + 2))
"$bin/log_player/lmf-player" --config "$config" --sim "$sim" "${player_mode[@]}" --start-delay-ms 1000 \
  "${key_args[@]}" "${loss_args[@]}" &
player=$!; pids+=($player); names+=(lmf-player)
if [[ -n ${LMF_SAMPLE_FILE:-} ]]; then sample & sampler=$!; fi
player_rc=0
wait "$player" || player_rc=$?
end=$(date +%s%N)
echo "replay took $(( (end - start) / 1000000 )) ms (wall clock)"

sleep "${LMF_SETTLE_S:-2}"  # agents ship their unfinished maps on mission end; let the server fuse them
for a in "${agents[@]}"; do stop "$a"; done
stop "$server"
stop "$monitor"
stop "$logger"
if [[ -n ${sampler:-} ]]; then kill "$sampler" 2>/dev/null || true; wait "$sampler" 2>/dev/null || true; fi
exit "$player_rc"
