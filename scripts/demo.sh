#!/usr/bin/env bash
# The README's main command: installs what is missing, builds, simulates a
# 3-robot mission in the built-in building, runs it as separate processes
# (lmf-server, three lmf-agent, lmf-player in lockstep, lmf-monitor and
# lcm-logger) inside a private network namespace, and prints the summary and
# the ATE against ground truth; then re-fuses the capture offline (lmf-server
# --replay) and checks it gives the same map. Everything goes to OUT (default: out/).
#   scripts/demo.sh [--rate R] [--secure] [--no-sightings]   (default: --lockstep, the fastest replay)
# --secure: lmf-keygen writes one keys file per process into OUT/keys and every
# process signs and verifies its messages (--keys); prints the rejections.
# --no-sightings: the player sends no sighting; robots after the first join only
# where a local map of theirs is placed without one (not built yet: they wait).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
out=${OUT:-$root/out}
build=${BUILD_DIR:-$root/build}
mode=(--lockstep)
secure=0
sightings=()
while [[ $# -gt 0 ]]; do
  case $1 in
    --rate) mode=(--rate "${2:?--rate needs a value}"); shift 2 ;;
    --secure) secure=1; shift ;;
    --no-sightings) sightings=(--no-sightings); shift ;;
    *) echo "usage: scripts/demo.sh [--rate R] [--secure] [--no-sightings]" >&2; exit 2 ;;
  esac
done

"$root/scripts/install-deps.sh"
# Only the programs the demo runs (not the tests and benchmarks).
demo_programs=(lmf-sim lmf-keygen lmf-server lmf-agent lmf-player lmf-monitor lmf-score)
echo "== building ${demo_programs[*]} (log: $out/build.log)"
mkdir -p "$out"
# What this run writes, removed first: a robot that does not join this time
# must not be scored with the trajectory an earlier run left.
rm -rf "$out/trajectories" "$out/replay" "$out/logs" "$out/map.svg" "$out/map.json" "$out/report.json" \
  "$out/trajectory.txt" "$out/timing.svg" "$out/lmf.lcmlog"
build_start=$(date +%s)
TARGETS="${demo_programs[*]}" BUILD_DIR=$build "$root/scripts/build.sh" >"$out/build.log" 2>&1 ||
  { tail -30 "$out/build.log"; exit 1; }
echo "   built in $(($(date +%s) - build_start)) s$(grep -h '^build: ccache' "$out/build.log" | sed 's/^build:/;/' || true)"

robots=3
echo "== simulating a $robots-robot, 20-minute mission (seed 1) into $out/sim"
"$build/tools/lmf-sim" --robots $robots --seed 1 --out "$out/sim"

if ((secure)); then
  echo "== generating keys: one file per process (mode 600) in $out/keys"
  "$build/tools/lmf-keygen" --robots $robots --out "$out/keys" --force
  export LMF_KEYS_DIR=$out/keys
fi

echo "== running server, agents, player (${mode[*]}), monitor and lcm-logger in a private network namespace"
# shellcheck source=lib/netns.sh
source "$root/scripts/lib/netns.sh"
lmf_netns_exec bash "$root/scripts/lib/run-mission.sh" "$build" "$out/sim" "$out" $robots "$root/config/sim.json" \
  "${mode[@]}" "${sightings[@]}"

echo "== summary"
for ((r = 0; r < robots; ++r)); do grep -h "scans" "$out/logs/agent$r.log" | tail -1 || true; done
python3 - "$out/report.json" <<'PY' 2>/dev/null || true
import json, sys
r = json.load(open(sys.argv[1]))
m, t, msg = r["map"], r["fusion_timing"], r["messages"]
print(f"lmf-server: {msg['local_maps_received']} local maps received, {msg['acks_fused']} fused "
      f"(p50 {t['p50_ms']:.1f} ms, p99 {t['p99_ms']:.1f} ms, max {t['max_ms']:.1f} ms); "
      f"map {m['segments']} segments, {m['submaps']} submaps, {m['graph_edges']} graph edges, "
      f"{m['robots_joined']} robots joined; P PSD throughout: {'yes' if r['global_covariance_always_ok'] else 'NO'}")
bodies = sum(f.get("footprint_segments_removed", 0) for f in r.get("fusions", []))
print(f"segments removed inside robot footprints (robot bodies seen by the lasers): {bodies}")
crossing = sum(f.get("crossing_segments_removed", 0) for f in r.get("fusions", []))
print(f"segments removed as the less certain of two that cross: {crossing}")
status = {}
for s in r.get("sightings", []): status[s["status"]] = status.get(s["status"], 0) + 1
print("sightings:", ", ".join(f"{n} {k}" for k, n in sorted(status.items())) or "none",
      "| rejected messages:", ", ".join(f"{n} {k}" for k, n in r.get("rejects", {}).items()) or "none")
PY
est=()
not_joined=()
for ((r = 0; r < robots; ++r)); do
  if [[ -s $out/trajectories/robot$r.txt ]]; then
    est+=(--est "$out/trajectories/robot$r.txt" --ref "$out/sim/robot$r.gt")
  else
    not_joined+=("robot$r")
  fi
done
if ((${#not_joined[@]})); then echo "not joined (no trajectory in the global frame): ${not_joined[*]}"; fi
echo -n "ATE against ground truth (the joined robots, one alignment): "
"$build/tools/lmf-score" "${est[@]}"
if ((secure)); then
  echo "== authentication (every message signed and verified; expected: 0 rejected)"
  grep -h "authentication:" "$out/logs/server.log" "$out"/logs/agent*.log "$out/logs/monitor.err" || true
  python3 - "$out/report.json" <<'PY' 2>/dev/null || true
import json, sys
rejects = json.load(open(sys.argv[1])).get("rejects", {})
print("server report.json rejects:", json.dumps(rejects) if rejects else "none")
PY
fi
echo "== the capture re-fused offline: lmf-server --replay $out/lmf.lcmlog --out $out/replay"
replay_keys=()
if ((secure)); then replay_keys=(--keys "$out/keys/server.keys"); fi
"$build/fusion_server/lmf-server" --replay "$out/lmf.lcmlog" --config "$root/config/sim.json" "${replay_keys[@]}" \
  --out "$out/replay" 2>&1 || true
python3 - "$out/map.json" "$out/replay/map.json" <<'PY' 2>/dev/null || echo "(no replayed map to compare)"
import json, sys
live, again = (json.load(open(f))["segments"] for f in sys.argv[1:3])
same = len(live) == len(again)
worst = max((abs(a - b) for s, t in zip(live, again) for k in ("start", "end") for a, b in zip(s[k], t[k])), default=0.0)
print(f"same map as the live server: {'yes' if same and worst < 1e-9 else 'NO'} "
      f"({len(again)} segments, largest endpoint difference {worst:.1e} m)")
PY
echo "== outputs in $out: map.svg map.json report.json trajectory.txt trajectories/ timing.svg lmf.lcmlog logs/ sim/ replay/"
