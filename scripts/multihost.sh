#!/usr/bin/env bash
# The lmf system across "machines", on one computer: lmf-server, one lmf-agent
# per robot, lmf-player (--lockstep), lmf-monitor and lcm-logger each run in
# their own network namespace with one interface (a veth pair into a Linux
# bridge), configured as on a real LAN: an address, `ip route add 224.0.0.0/4
# dev eth0`, LCM URL udpm://239.255.76.67:7667?ttl=1. The bridge and all the
# machines sit inside one private outer namespace (scripts/lib/netns.sh), so no
# interface is created and no packet is sent on the host network. Simulates a
# short mission with lmf-sim, replays it, prints where each process ran, the
# player's summary, the server's fusion report and the ATE against ground truth.
#   scripts/multihost.sh [--robots N] [--out DIR] [--duration-s S] [--seed K] [--timeout-s T]
# Defaults: 2 robots, out/multihost, 90 s simulated mission, seed 1, 300 s timeout.
# BUILD_DIR (default build/) holds the binaries; scripts/build.sh runs if one is missing.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${BUILD_DIR:-$root/build}
robots=2 out=$root/out/multihost duration=90 seed=1 timeout_s=300

usage() { sed -n '2,13s/^# \{0,1\}//p' "$0"; }
while (($#)); do
  case $1 in
    --robots) robots=${2:?--robots needs a value}; shift 2 ;;
    --out) out=${2:?--out needs a value}; shift 2 ;;
    --duration-s) duration=${2:?--duration-s needs a value}; shift 2 ;;
    --seed) seed=${2:?--seed needs a value}; shift 2 ;;
    --timeout-s) timeout_s=${2:?--timeout-s needs a value}; shift 2 ;;
    -h | --help) usage; exit 0 ;;
    *) echo "multihost.sh: unknown option '$1'" >&2; usage >&2; exit 2 ;;
  esac
done
[[ $robots =~ ^[1-8]$ ]] || { echo "multihost.sh: --robots must be 1..8 (got '$robots')" >&2; exit 2; }
[[ $timeout_s =~ ^[1-9][0-9]*$ ]] || { echo "multihost.sh: --timeout-s must be a positive integer" >&2; exit 2; }
mkdir -p "$out"
out=$(cd "$out" && pwd)

# shellcheck source=SCRIPTDIR/lib/netns.sh
source "$root/scripts/lib/netns.sh"
if ! lmf_netns_supported; then
  echo "multihost.sh: cannot create private network namespaces here (needs unshare -rn or root, and iproute2)" >&2
  exit 4
fi
command -v lcm-logger >/dev/null || { echo "multihost.sh: lcm-logger not found (scripts/install-deps.sh)" >&2; exit 4; }

bins=(fusion_server/lmf-server robot_agent/lmf-agent log_player/lmf-player monitor/lmf-monitor tools/lmf-sim tools/lmf-score)
for b in "${bins[@]}"; do
  if [[ ! -x $build/$b ]]; then
    echo "== building into $build (log: $out/build.log)"
    BUILD_DIR=$build "$root/scripts/build.sh" >"$out/build.log" 2>&1 || { tail -30 "$out/build.log"; exit 1; }
    break
  fi
done

# Nothing of an earlier run may count in this one (a 3-robot run's robot2 files
# and logs would be read as a third robot here).
rm -rf "$out/sim" "$out/logs" "$out/hosts" "$out/trajectories" "$out/report.json"
echo "== simulating a $robots-robot, ${duration}-second mission (seed $seed) into $out/sim"
"$build/tools/lmf-sim" --robots "$robots" --seed "$seed" --duration-s "$duration" --out "$out/sim" >"$out/sim.log"

echo "== running each process on its own machine (private namespaces, timeout ${timeout_s} s)"
# timeout runs in its own process group: on a signal the trap stops that group
# (the outer namespace's first process cleans up; the rest dies with it).
mission_pid=
stop_mission() {
  [[ -n $mission_pid ]] && kill -0 "$mission_pid" 2>/dev/null || return 0
  kill -TERM -- "-$mission_pid" 2>/dev/null || true
  for _ in $(seq 50); do kill -0 "$mission_pid" 2>/dev/null || return 0; sleep 0.1; done
  kill -KILL -- "-$mission_pid" 2>/dev/null || true
}
trap stop_mission EXIT
trap 'exit 130' INT TERM
# shellcheck disable=SC2016
timeout --kill-after=10 "$timeout_s" bash -c 'source "$1" && shift && lmf_netns_exec "$@"' _ \
  "$root/scripts/lib/netns.sh" bash "$root/scripts/lib/multihost-mission.sh" \
  "$build" "$out/sim" "$out" "$robots" "$root/config/sim.json" &
mission_pid=$!
status=0
wait "$mission_pid" || status=$?
mission_pid=
if ((status == 124 || status == 137)); then
  echo "multihost.sh: the mission did not finish within ${timeout_s} s (--timeout-s); logs in $out/logs" >&2
  exit 1
elif ((status != 0)); then
  echo "multihost.sh: the mission failed (status $status); logs in $out/logs" >&2
  exit 1
fi

echo "== player summary"
head -n 1 "$out/logs/player.log"
tail -n 1 "$out/logs/player.log"
for ((r = 0; r < robots; ++r)); do grep -h "scans" "$out/logs/agent$r.log" | tail -1 || true; done

echo "== server report ($out/report.json)"
[[ -f $out/report.json ]] || { echo "multihost.sh: the server wrote no report.json" >&2; exit 1; }
# Every local map an agent shipped crossed the bridge to the server and was fused.
python3 - "$out/report.json" "$robots" "$out"/logs/agent*.log <<'PY'
import json, re, sys
r = json.load(open(sys.argv[1]))
print(json.dumps({k: r[k] for k in r if k not in ("fusions", "sightings")}, indent=1)[:1500])
robots = int(sys.argv[2])
shipped = 0
for path in sys.argv[3:]:
    found = re.findall(r"(\d+) local maps shipped", open(path).read())
    shipped += int(found[-1]) if found else 0
fused = sum(x["local_maps_fused"] for x in r["robots"])
joined = r["map"]["robots_joined"]
print(f"local maps shipped by the agents: {shipped}, fused by the server: {fused}, robots joined: {joined}/{robots}")
if shipped == 0 or fused != shipped or joined != robots:
    sys.exit("multihost.sh: the server did not fuse every local map of every robot")
PY

est=()
for ((r = 0; r < robots; ++r)); do est+=(--est "$out/trajectories/robot$r.txt" --ref "$out/sim/robot$r.gt"); done
echo -n "== ATE against ground truth (all robots, one alignment): "
"$build/tools/lmf-score" "${est[@]}"
echo "== outputs in $out: report.json map.svg trajectories/ timing.svg lmf.lcmlog logs/ hosts/ sim/"
