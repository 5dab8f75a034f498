#!/usr/bin/env bash
# End-to-end test of the real binaries: a short 2-robot simulated mission run as
# separate processes (lmf-server, two lmf-agent, lmf-player --lockstep,
# lmf-monitor, lcm-logger) inside a private network namespace must give the
# same trajectories as lmf-offline on the same input, within 1 cm; the monitor's
# JSON lines must parse and the capture must read back (lmf-monitor --log), and
# lmf-server --replay on the capture must give the live server's map again.
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
# lmf-server --replay on the capture: the live server's map again.
"$build/fusion_server/lmf-server" --replay "$work/distributed/lmf.lcmlog" --config "$config" \
  --out "$work/replay" 2>"$work/replay.log" || { cat "$work/replay.log"; status=1; }
cat "$work/replay.log"
python3 - "$work/distributed/map.json" "$work/replay/map.json" <<'PY' || status=1
import json, sys
live, again = (json.load(open(f)) for f in sys.argv[1:3])
assert live["counts"] == again["counts"], f"counts {again['counts']} vs live {live['counts']}"
worst = max((abs(a - b) for s, t in zip(live["segments"], again["segments"]) for k in ("start", "end")
             for a, b in zip(s[k], t[k])), default=0.0)
assert worst < 1e-9, f"replayed segments differ from the live ones by up to {worst} m"
print(f"lmf-server --replay: the live map again ({len(again['segments'])} segments, largest difference {worst:.1e} m)")
PY
"$build/fusion_server/lmf-server" --replay "$work/no-such.lcmlog" --out "$work/none" 2>"$work/missing.log" \
  && { echo "FAIL: a missing capture was accepted"; status=1; }
grep -q "no-such.lcmlog" "$work/missing.log" || { echo "FAIL: the error does not name the file"; cat "$work/missing.log"; status=1; }
exit $status
