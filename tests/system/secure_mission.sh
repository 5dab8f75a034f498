#!/usr/bin/env bash
# End-to-end test of authenticated messages with the real binaries: lmf-keygen
# writes one keys file per process; a short 2-robot simulated mission runs as
# separate processes, every one with --keys, inside a private network
# namespace (scripts/lib/run-mission.sh with LMF_KEYS_DIR). Checks: every local
# map shipped is acknowledged, every process verified messages and rejected
# none, every event of the lcm-logger capture carries a trailer after an
# intact LCM encoding and lmf-monitor --log reads the capture; a keys file
# readable by others and an agent signing as another robot are refused.
#   secure_mission.sh BUILD_DIR SOURCE_DIR
# Exit 77 (skipped) when no private network namespace can be made here.
set -euo pipefail
build=$1 src=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
source "$src/scripts/lib/netns.sh"
if ! lmf_netns_supported; then echo "SKIP: cannot create a private network namespace here"; exit 77; fi
status=0
fail() { echo "FAIL: $*"; status=1; }

"$build/tools/lmf-keygen" --robots 2 --out "$work/keys"
[[ $(stat -c %a "$work/keys/server.keys") == 600 ]] || fail "server.keys is not mode 600"
if "$build/tools/lmf-keygen" --robots 2 --out "$work/keys" 2>/dev/null; then fail "lmf-keygen overwrote keys without --force"; fi

# Refusals, before any message: a keys file others can read, a robot without the other robot's key.
cp "$work/keys/server.keys" "$work/open.keys" && chmod 644 "$work/open.keys"
if "$build/fusion_server/lmf-server" --keys "$work/open.keys" --out "$work/unused" 2>"$work/err"; then
  fail "lmf-server started with a keys file readable by others"
fi
grep -q "chmod 600" "$work/err" || fail "no clear error for mode 644: $(cat "$work/err")"
if "$build/robot_agent/lmf-agent" --robot-id 0 --keys "$work/keys/robot0.keys" --identity robot1 2>"$work/err"; then
  fail "lmf-agent 0 signed as robot1"
fi
grep -q "no key for 'robot1'" "$work/err" || fail "no clear error for a foreign identity: $(cat "$work/err")"

config=$src/config/sim.json
"$build/tools/lmf-sim" --robots 2 --seed 5 --duration-s 45 --out "$work/sim" >/dev/null
LMF_KEYS_DIR=$work/keys timeout 240 bash -c 'source "$1/scripts/lib/netns.sh"; shift; lmf_netns_exec bash "$@"' _ \
  "$src" "$src/scripts/lib/run-mission.sh" "$build" "$work/sim" "$work/run" 2 "$config" --lockstep --quiet \
  >"$work/player.log" 2>&1 || { cat "$work/player.log"; fail "the mission did not run"; }
out=$work/run

for r in 0 1; do
  line=$(grep -h "local maps shipped" "$out/logs/agent$r.log" | tail -1)
  echo "agent $r: $line"
  shipped=$(sed -n 's/.* \([0-9]*\) local maps shipped, \([0-9]*\) acknowledged.*/\1 \2/p' <<<"$line")
  read -r s a <<<"$shipped"
  [[ -n ${s:-} && $s -gt 0 && $s == "$a" ]] || fail "robot $r: shipped/acknowledged '$shipped'"
done
for log in "$out/logs/server.log" "$out/logs/agent0.log" "$out/logs/agent1.log" "$out/logs/monitor.err" \
           "$work/player.log"; do
  line=$(grep -h "authentication:" "$log" | tail -1 || true)
  echo "$(basename "$log"): $line"
  [[ $line =~ ([0-9]+)\ messages\ verified.*\ 0\ rejected$ && ${BASH_REMATCH[1]} -gt 0 ]] ||
    fail "$(basename "$log"): expected messages verified and 0 rejected"
done

python3 - "$out/lmf.lcmlog" <<'PY' || fail "capture"
import struct, sys
data = open(sys.argv[1], "rb").read()
pos, events, signed = 0, 0, 0
while pos + 28 <= len(data):
    sync, _, _, clen, dlen = struct.unpack(">IqqII", data[pos:pos + 28])
    assert sync == 0xEDA1DA01, f"bad sync at {pos}"
    channel = data[pos + 28:pos + 28 + clen].decode()
    payload = data[pos + 28 + clen:pos + 28 + clen + dlen]
    pos += 28 + clen + dlen
    if not channel.startswith("LMF_"):
        continue
    events += 1
    # payload | principal | n | seq (8) | tag (32) | version 1 | "LMFA"
    if payload[-4:] == b"LMFA" and payload[-5] == 1:
        n = payload[-5 - 32 - 8 - 1]
        principal = payload[-46 - n:-46].decode()
        assert principal in ("server", "player") or principal.startswith("robot"), principal
        signed += 1
assert events > 0 and signed == events, f"{signed} of {events} LMF_ events signed"
print(f"capture: {events} LMF_ events, all signed")
PY
"$build/monitor/lmf-monitor" --log "$out/lmf.lcmlog" --json >"$work/replayed.jsonl" 2>"$work/monitor-log.err"
python3 - "$work/replayed.jsonl" <<'PY' || fail "lmf-monitor --log on the signed capture"
import json, sys
lines = [json.loads(l) for l in open(sys.argv[1]) if l.strip()]
assert lines, "no JSON line"
text = json.dumps(lines[-1])
assert "decode_failed" not in text, "the monitor could not decode the signed capture: " + text[:400]
print(f"monitor --log on the signed capture: {len(lines)} JSON lines, no decode failure")
PY
exit $status
