#!/usr/bin/env bash
# End-to-end test of the real binaries: a short 2-robot simulated mission run as
# separate processes (lmf-server, two lmf-agent, lmf-player --lockstep,
# lmf-monitor, lcm-logger) inside a private network namespace must give the
# same trajectories as lmf-offline on the same input, within 1 cm; the monitor's
# JSON lines must parse and the capture must read back.
#   distributed_matches_offline.sh BUILD_DIR SOURCE_DIR
# Exit 77 (skipped) when no private network namespace can be made here.
set -euo pipefail
build=$1 src=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
source "$src/scripts/lib/netns.sh"
if ! lmf_netns_supported; then echo "SKIP: cannot create a private network namespace here"; exit 77; fi

config=$src/config/sim.json
"$build/tools/lmf-sim" --robots 2 --seed 5 --duration-s 90 --out "$work/sim" >/dev/null
"$build/tools/lmf-offline" --sim "$work/sim" --config "$config" --out "$work/offline" >/dev/null
timeout 240 bash -c 'source "$1/scripts/lib/netns.sh"; shift; lmf_netns_exec bash "$@"' _ "$src" \
  "$src/scripts/lib/run-mission.sh" "$build" "$work/sim" "$work/distributed" 2 "$config" --lockstep --quiet

status=0
for r in 0 1; do
  line=$("$build/tools/lmf-score" --json --no-align --est "$work/distributed/trajectories/robot$r.txt" \
         --ref "$work/offline/trajectories/robot$r.txt")
  echo "robot$r distributed vs offline: $line"
  python3 - "$line" "$(wc -l <"$work/offline/trajectories/robot$r.txt")" <<'PY' || status=1
import json, sys
s = json.loads(sys.argv[1]); expected = int(sys.argv[2])
assert s["poses"] == expected, f"{s['poses']} poses scored, offline has {expected}"
assert s["ate_position_rmse_m"] < 0.01, f"distributed differs from offline by {s['ate_position_rmse_m']} m RMS"
PY
done
python3 - "$work/distributed/logs/monitor.jsonl" <<'PY' || status=1
import json, sys
lines = [l for l in open(sys.argv[1]) if l.strip()]
assert lines, "the monitor printed no JSON line"
for l in lines: json.loads(l)
print(f"monitor: {len(lines)} JSON lines parse")
PY
"$build/monitor/lmf-monitor" --log "$work/distributed/lmf.lcmlog" --json >"$work/replayed.jsonl"
python3 -c "import json,sys; [json.loads(l) for l in open(sys.argv[1]) if l.strip()]" "$work/replayed.jsonl" || status=1
echo "monitor --log on the capture: $(grep -c . "$work/replayed.jsonl") JSON lines"
exit $status
