#!/usr/bin/env bash
# lmf-server started after the replay (the real binaries, 2 robots, lockstep,
# inside a private network namespace): the agents resend their local maps and
# the player its sightings until the server answers, so robot 1, which joins
# only through a sighting, is in the map and every scan has a pose. The player
# runs with --max-attempts 0 (no limit), as for a server of unknown start.
#   late_server.sh BUILD_DIR SOURCE_DIR
set -euo pipefail
build=$1 src=$2

if [[ ${3:-} != --inside ]]; then
  work=$(mktemp -d)
  [[ -n ${LMF_TEST_KEEP:-} ]] && echo "keeping $work" || trap 'rm -rf "$work"' EXIT
  source "$src/scripts/lib/netns.sh"
  if ! lmf_netns_supported; then echo "SKIP: cannot create a private network namespace here"; exit 77; fi
  "$build/tools/lmf-sim" --robots 2 --seed 5 --duration-s 120 --out "$work/sim" >/dev/null
  status=0
  timeout 240 bash -c 'source "$1/scripts/lib/netns.sh"; shift; lmf_netns_exec bash "$@"' _ "$src" \
    "$0" "$build" "$src" --inside "$work" || status=$?
  if [[ $status -ne 0 ]]; then
    for log in "$work"/logs/*.log; do echo "---- $log (tail)"; tail -n 15 "$log"; done
  fi
  exit $status
fi

work=$4
config=$src/config/sim.json
mkdir -p "$work/logs" "$work/out"
pids=()
cleanup() {
  for pid in "${pids[@]}"; do kill "$pid" 2>/dev/null || true; done
  wait 2>/dev/null || true
}
trap cleanup EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

for r in 0 1; do
  "$build/robot_agent/lmf-agent" --config "$config" --robot-id "$r" --resend-interval-ms 300 \
    >"$work/logs/agent$r.log" 2>&1 & pids+=($!)
done
"$build/log_player/lmf-player" --config "$config" --sim "$work/sim" --lockstep --start-delay-ms 500 \
  --ack-timeout-ms 500 --max-attempts 0 >"$work/logs/player.log" 2>&1 & player=$!; pids+=($player)
# The server starts once the player has sent every scan (and so every sighting).
deadline=$((SECONDS + 120))
until grep -q '(100.0 %)' "$work/logs/player.log" 2>/dev/null; do
  ((SECONDS < deadline)) || fail "the replay did not finish"
  sleep 0.1
done
"$build/fusion_server/lmf-server" --config "$config" --out "$work/out" >"$work/logs/server.log" 2>&1 & server=$!
pids+=($server)
wait "$player" || fail "lmf-player exited with $?"
sleep 3  # the agents' last maps (shipped at mission end) reach the server
kill -TERM "$server"; wait "$server" || fail "lmf-server exited with $?"

summary=$(tail -n 1 "$work/logs/player.log")
echo "player: $summary"
python3 - "$work" "$summary" <<'PY'
import json, re, sys
work, summary = sys.argv[1], sys.argv[2]
report = json.load(open(f"{work}/out/report.json"))
published = int(re.search(r"sightings published (\d+)/", summary).group(1))
resends = int(re.search(r", resends (\d+), acked", summary).group(1))
acked = int(re.search(r", acked (\d+), rejected", summary).group(1))
unanswered = int(re.search(r"unanswered (\d+)", summary).group(1))
fused = {r["robot_id"]: r["local_maps_fused"] for r in report["robots"]}
poses = sum(1 for _ in open(f"{work}/out/trajectory.txt"))
scans = sum(line.startswith("FLASER") for r in (0, 1) for line in open(f"{work}/sim/robot{r}.log"))
print(f"sightings: {published} published, {resends} resends, {acked} acked, {unanswered} unanswered; "
      f"server: {report['sightings']}; local maps fused per robot {fused}; {poses} trajectory poses")
problems = []
if published == 0: problems.append("no sighting was published")
if resends == 0: problems.append("no sighting was resent: the server was up before they went out?")
if acked != published or unanswered: problems.append("not every sighting was answered")
if fused.get(1, 0) == 0: problems.append("robot 1 did not join")
if poses != scans: problems.append(f"{poses} trajectory poses for {scans} scans")
if report["sightings"] and report["sightings"][0]["status"] != "joined":
    problems.append("the first sighting (in time order) did not join robot 1")
if problems: sys.exit("FAIL: " + "; ".join(problems))
PY
