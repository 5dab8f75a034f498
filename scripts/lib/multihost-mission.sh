#!/usr/bin/env bash
# The distributed mission of scripts/lib/run-mission.sh, but with every process
# on its own "machine": a nested network namespace joined by a veth pair to one
# Linux bridge, LCM over udpm://239.255.76.67:7667?ttl=1 like across a real
# LAN. Runs as the first process of the private outer namespace made by
# lmf_netns_exec (scripts/multihost.sh); the bridge and the host ends of the
# veths live in that outer namespace, so nothing touches the host network.
# Stops every process it started; the nested namespaces die with them.
#   multihost-mission.sh BIN_DIR SIM_DIR OUT_DIR NUM_ROBOTS CONFIG
set -euo pipefail
lib=$(cd "$(dirname "$0")" && pwd)
bin=$1 sim=$2 out=$3 robots=$4 config=$5
# shellcheck source=SCRIPTDIR/netns.sh
source "$lib/netns.sh"

# Safety: the bridge and veths are created only in a namespace that has
# nothing but lo (lmf_netns_setup already checked; check again right here).
if ! lmf_netns_is_private; then
  echo "multihost: refusing: not in a private network namespace" >&2
  exit 3
fi

hosts="$out/hosts"
rm -rf "$hosts"
mkdir -p "$out/logs" "$hosts"

pids=()
# shellcheck disable=SC2317  # called by the EXIT trap
cleanup() {
  for pid in "${pids[@]}"; do kill -TERM "$pid" 2>/dev/null || true; done
  sleep 0.5
  for pid in "${pids[@]}"; do kill -KILL "$pid" 2>/dev/null || true; done
  wait 2>/dev/null || true
  ip link del lmfbr0 2>/dev/null || true
}
trap cleanup EXIT
trap 'exit 143' TERM INT  # as PID 1 of the namespace only handled signals arrive

stop() {  # SIGTERM one process and wait for it (bounded)
  local pid=$1
  kill -TERM "$pid" 2>/dev/null || return 0
  for _ in $(seq 100); do kill -0 "$pid" 2>/dev/null || { wait "$pid" 2>/dev/null || true; return 0; }; sleep 0.1; done
  kill -KILL "$pid" 2>/dev/null || true
}

ip link add lmfbr0 type bridge
# No IGMP querier on this LAN: without snooping the bridge floods multicast to
# every port, like a plain switch.
ip link set lmfbr0 type bridge mcast_snooping 0
ip link set lmfbr0 up

next_host=0
# start_host NAME LOG ERR_LOG CMD... : runs CMD on a new machine NAME
# (10.76.0.<n+1>/24), stdout to LOG, stderr to ERR_LOG; sets $host_pid.
# Returns once the machine's eth0 is configured.
start_host() {
  local name=$1 log=$2 err=$3 n=$((++next_host))
  shift 3
  if [[ $err == "$log" ]]; then
    unshare -n bash "$lib/multihost-node.sh" "10.76.0.$n/24" "$hosts/$name" "$@" >"$log" 2>&1 &
  else
    unshare -n bash "$lib/multihost-node.sh" "10.76.0.$n/24" "$hosts/$name" "$@" >"$log" 2>"$err" &
  fi
  host_pid=$!
  pids+=("$host_pid")
  # $! is known before unshare has made the namespace: wait for it, or the
  # peer would land in this (outer) namespace.
  local own
  own=$(readlink /proc/self/ns/net)
  for _ in $(seq 200); do
    [[ $(readlink "/proc/$host_pid/ns/net" 2>/dev/null || echo "$own") != "$own" ]] && break
    sleep 0.02
  done
  if [[ $(readlink "/proc/$host_pid/ns/net" 2>/dev/null || echo "$own") == "$own" ]]; then
    echo "multihost: machine $name got no network namespace; its log:" >&2
    cat "$err" >&2
    exit 1
  fi
  ip link add "lmfv$n" type veth peer name eth0 netns "$host_pid"
  ip link set "lmfv$n" master lmfbr0
  ip link set "lmfv$n" up
  for _ in $(seq 200); do [[ -f $hosts/$name ]] && break; sleep 0.05; done
  if [[ ! -f $hosts/$name ]]; then
    echo "multihost: machine $name did not come up; its log:" >&2
    cat "$err" >&2
    exit 1
  fi
  read -r ip ns <"$hosts/$name"
  printf '  %-10s netns %-18s %-11s pid %-5s %s\n' "$name" "$ns" "$ip" "$host_pid" "$(basename "$1")"
}

echo "machines (one network namespace each, veth -> bridge lmfbr0, LCM udpm://239.255.76.67:7667?ttl=1):"
start_host logger "$out/logs/logger.log" "$out/logs/logger.log" lcm-logger -q --force "$out/lmf.lcmlog"; logger=$host_pid
start_host server "$out/logs/server.log" "$out/logs/server.log" "$bin/fusion_server/lmf-server" --config "$config" --out "$out"; server=$host_pid
agents=()
for ((r = 0; r < robots; ++r)); do
  start_host "robot$r" "$out/logs/agent$r.log" "$out/logs/agent$r.log" "$bin/robot_agent/lmf-agent" --config "$config" --robot-id "$r"
  agents+=("$host_pid")
done
start_host monitor "$out/logs/monitor.jsonl" "$out/logs/monitor.err" "$bin/monitor/lmf-monitor" --json --timing-svg "$out/timing.svg"
monitor=$host_pid

start=$(date +%s%N)
start_host player "$out/logs/player.log" "$out/logs/player.log" "$bin/log_player/lmf-player" --config "$config" --sim "$sim" --lockstep \
  --start-delay-ms 1000
player=$host_pid
status=0
wait "$player" || status=$?
end=$(date +%s%N)
echo "player exited with status $status; replay took $(( (end - start) / 1000000 )) ms (wall clock)"

sleep 2  # agents ship their unfinished maps on mission end; let the server fuse them
for a in "${agents[@]}"; do stop "$a"; done
stop "$server"
stop "$monitor"
stop "$logger"
echo "traffic over each machine's eth0 (through the bridge):"
for f in "$hosts"/*.traffic; do
  [[ -f $f ]] || continue
  read -r sent received <"$f"
  printf '  %-10s sent %11s B  received %11s B\n' "$(basename "$f" .traffic)" "$sent" "$received"
done
exit "$status"
