#!/usr/bin/env bash
# Kill and restart one agent: a short 2-robot simulated mission run as
# separate processes (lmf-server, two lmf-agent, lmf-player --lockstep) inside a
# private network namespace. Robot 1's agent runs with --state; it is made to
# stall after a scan past the middle of its log (--test-stall-after-scan, so the
# kill lands at a known point, mid-map, after it shipped maps), is killed with
# SIGKILL, and restarted on the same --state while the player keeps resending
# the scan it waits for. Before the kill its map transmissions are dropped with
# a seeded 50 % loss and no resend is due, so that it dies with map 0
# acknowledged and map 1 shipped but never received by the server. Checks:
#  * the mission completes: the player gives up no scan, both agents report
#    every local map they shipped acknowledged;
#  * the server's report lists, for each robot, the seqs 0..N-1 exactly once,
#    N = the maps that robot shipped (so every map the server acknowledged,
#    before or after the kill, is in the final map; no seq lost or applied twice);
#  * the restarted agent resumed with >= 1 map acknowledged and >= 1 to resend,
#    bridged the lost scans by odometry, and robot 1's trajectory lacks exactly
#    those scans;
#  * robot 1's ATE against the simulator's truth, printed with the uninterrupted
#    run's (lmf-offline, equal to a lockstep run), within 3x + 0.1 m of it.
#   agent_restart.sh BUILD_DIR SOURCE_DIR
# Exit 77 (skipped) when no private network namespace can be made here.
set -euo pipefail
build=$1 src=$2
config=$src/config/sim.json

if [[ ${3:-} == inside ]]; then  # ---- inside the namespace: the processes ----
  work=$4 stall=$5
  out=$work/run
  mkdir -p "$out/logs"
  pids=()
  cleanup() {
    for pid in "${pids[@]}"; do kill -KILL "$pid" 2>/dev/null || true; done
    wait 2>/dev/null || true
  }
  trap cleanup EXIT
  stop() {  # SIGTERM one process and wait for it (bounded)
    local pid=$1
    kill -TERM "$pid" 2>/dev/null || return 0
    for _ in $(seq 100); do kill -0 "$pid" 2>/dev/null || { wait "$pid" 2>/dev/null || true; return 0; }; sleep 0.1; done
    kill -KILL "$pid" 2>/dev/null || true
  }
  # Run in the background (`agent ... &`): exec, so $! is the agent itself.
  agent() { exec "$build/robot_agent/lmf-agent" --config "$config" "$@"; }

  "$build/fusion_server/lmf-server" --config "$config" --out "$out" >"$out/logs/server.log" 2>&1 & server=$!
  pids+=($server)
  agent --robot-id 0 --resend-interval-ms 300 >"$out/logs/agent0.log" 2>&1 & agent0=$!
  pids+=($agent0)
  # Seed 3: the first transmission (map 0) goes out, the second (map 1) is dropped and never
  # resent; the ack of the scan that shipped it waits 100 ms for an answer that cannot come.
  agent --robot-id 1 --state "$work/state" --test-stall-after-scan "$stall" --resend-interval-ms 600000 \
    --min-resend-interval-ms 600000 --ack-hold-ms 100 \
    --drop-local-maps 0.5 --drop-seed 3 >"$out/logs/agent1-killed.log" 2>&1 &
  agent1=$!
  pids+=($agent1)
  "$build/log_player/lmf-player" --config "$config" --sim "$work/sim" --lockstep --quiet --start-delay-ms 1000 \
    --ack-timeout-ms 500 --max-attempts 100 >"$out/logs/player.log" 2>&1 & player=$!
  pids+=($player)

  for _ in $(seq 600); do
    grep -q "stalled after scan" "$out/logs/agent1-killed.log" && break
    kill -0 "$player" 2>/dev/null || break
    sleep 0.1
  done
  if ! grep -q "stalled after scan" "$out/logs/agent1-killed.log"; then
    echo "FAIL: agent 1 never reached scan $stall"; cat "$out/logs/agent1-killed.log"; exit 1
  fi
  kill -KILL "$agent1"
  wait "$agent1" 2>/dev/null || true
  echo "agent 1 killed (SIGKILL) after scan $stall"
  sleep 1  # the player resends the scan it waits for, to nobody
  agent --robot-id 1 --state "$work/state" --resend-interval-ms 300 >"$out/logs/agent1-restarted.log" 2>&1 &
  agent1=$!
  pids+=($agent1)
  player_status=0
  wait "$player" || player_status=$?
  sleep 2  # agents ship their unfinished maps on mission end; let the server fuse them
  stop "$agent0"
  stop "$agent1"
  stop "$server"
  cat "$out/logs/player.log"
  exit $player_status
fi

# ---- outside: set up, run, check ----
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
source "$src/scripts/lib/netns.sh"
if ! lmf_netns_supported; then echo "SKIP: cannot create a private network namespace here"; exit 77; fi

# --robot-gap-m 0: the mission this test was written on (robots drive their
# routes on the clock). With the simulator's default, robot 1 waits for robot 0
# once, its stall falls 0.4 m before a corner, and the restart's 49 scans
# bridged by odometry then cost 0.34 m of ATE (0.05 m uninterrupted): a
# limit of bridging by odometry alone (docs/reliability.md), not of the restart.
"$build/tools/lmf-sim" --robots 2 --seed 5 --duration-s 90 --robot-gap-m 0 --out "$work/sim" >/dev/null
"$build/tools/lmf-offline" --sim "$work/sim" --config "$config" --out "$work/offline" >/dev/null
scans1=$(grep -c '^FLASER' "$work/sim/robot1.log")
stall=$((scans1 * 3 / 5))
start=$(date +%s%N)
timeout 150 bash -c 'source "$1/scripts/lib/netns.sh"; shift; lmf_netns_exec bash "$@"' _ "$src" \
  "$0" "$build" "$src" inside "$work" "$stall"
echo "distributed run with the restart took $(( ($(date +%s%N) - start) / 1000000 )) ms (wall clock)"
logs=$work/run/logs
echo "--- agent 1 (killed):";    cat "$logs/agent1-killed.log"
echo "--- agent 1 (restarted):"; cat "$logs/agent1-restarted.log"
echo "--- agent 0:";             tail -1 "$logs/agent0.log"

score() {  # robot, estimate file -> one JSON line
  "$build/tools/lmf-score" --json --est "$2" --ref "$work/sim/robot$1.gt"
}
python3 - "$work/run/report.json" "$logs/agent0.log" "$logs/agent1-restarted.log" \
  "$(score 1 "$work/run/trajectories/robot1.txt")" "$(score 1 "$work/offline/trajectories/robot1.txt")" \
  "$(score 0 "$work/run/trajectories/robot0.txt")" "$(score 0 "$work/offline/trajectories/robot0.txt")" <<'PY'
import collections, json, re, sys
report_file, agent0_log, agent1_log, run1, off1, run0, off0 = sys.argv[1:]
report = json.load(open(report_file))
fused = collections.Counter((f["robot_id"], f["seq"]) for f in report["fusions"])
failures = []

def summary(log):  # the agent's last line: "...; S scans, N local maps shipped, A acknowledged, ..."
    m = re.search(r"(\d+) scans, (\d+) local maps shipped, (\d+) acknowledged", open(log).read())
    if not m: failures.append(f"no summary in {log}"); return None
    return tuple(int(g) for g in m.groups())

restarted = open(agent1_log).read()
resumed = re.search(r"resumed from .*: local map (\d+) from its origin at scan (\d+), (\d+) local map\(s\) shipped, "
                    r"(\d+) acknowledged, (\d+) unacknowledged", restarted)
bridged = re.search(r"first scan after the restart: (\d+), (\d+) scan\(s\)", restarted)
if not resumed or not bridged:
    failures.append("the restarted agent did not resume from its state")
else:
    map_seq, origin, shipped, acked, unacked = (int(g) for g in resumed.groups())
    print(f"restarted agent 1: resumed local map {map_seq} from its origin at scan {origin}; before the kill "
          f"{shipped} maps shipped, {acked} acknowledged, {unacked} resent now; first scan {bridged.group(1)}, "
          f"{bridged.group(2)} scans bridged by odometry")
    if acked < 1 or unacked < 1: failures.append("the kill did not leave both an acknowledged and an unacknowledged map")

for robot, log in ((0, agent0_log), (1, agent1_log)):
    s = summary(log)
    if s is None: continue
    _, shipped, acked = s
    seqs = sorted(seq for (r, seq) in fused if r == robot)
    twice = [seq for (r, seq), n in fused.items() if r == robot and n > 1]
    print(f"robot {robot}: {shipped} local maps shipped, {acked} acknowledged; server fused seqs {seqs}")
    if acked != shipped: failures.append(f"robot {robot}: {shipped - acked} maps never acknowledged")
    if seqs != list(range(shipped)): failures.append(f"robot {robot}: fused seqs {seqs}, expected 0..{shipped - 1}")
    if twice: failures.append(f"robot {robot}: seqs applied twice: {twice}")

r1, o1, r0, o0 = (json.loads(x) for x in (run1, off1, run0, off0))
print(f"ATE robot 1 (restarted): {r1['ate_position_rmse_m']:.3f} m over {r1['poses']} poses; "
      f"uninterrupted: {o1['ate_position_rmse_m']:.3f} m over {o1['poses']} poses")
print(f"ATE robot 0: {r0['ate_position_rmse_m']:.3f} m; uninterrupted: {o0['ate_position_rmse_m']:.3f} m")
if bridged and r1["poses"] != o1["poses"] - int(bridged.group(2)):
    failures.append(f"robot 1 has {r1['poses']} poses, expected {o1['poses']} - {bridged.group(2)} bridged")
if not r1["ate_position_rmse_m"] < 3 * o1["ate_position_rmse_m"] + 0.1:
    failures.append("robot 1's ATE after the restart is far from the uninterrupted run's")
for f in failures: print("FAIL:", f)
sys.exit(1 if failures else 0)
PY
