#!/usr/bin/env bash
# The 2-minute version of scripts/soak.sh: a 3-robot, 120 s mission in lockstep
# (every local map acknowledged, trajectories equal to lmf-offline's), then a
# 60 s one at --rate 8 with 10 % of every process's messages lost; each writes
# soak.json (checked here) and soak.svg.
# Usage: soak_smoke.sh BUILD_DIR SOURCE_DIR. Exit 77 without network namespaces.
set -euo pipefail
build=$1 src=$2
source "$src/scripts/lib/netns.sh"
if ! lmf_netns_supported; then echo "SKIP: cannot create a private network namespace here"; exit 77; fi
out=$(mktemp -d "${TMPDIR:-/tmp}/lmf-soak-smoke.XXXXXX")
trap 'rm -rf "$out"' EXIT
timeout 240 bash "$src/scripts/soak.sh" --build "$build" --robots 3 --duration-s 120 --lockstep --out "$out/lockstep"
timeout 240 bash "$src/scripts/soak.sh" --build "$build" --robots 3 --duration-s 60 --rate 8 --loss 0.1 \
  --out "$out/lossy"
python3 - "$out/lockstep/soak.json" "$out/lossy/soak.json" <<'PY'
import json, sys
for path in sys.argv[1:]:
    s = json.load(open(path))
    assert s["passed"] and not s["failures"], f"{path}: {s['failures']}"
    assert s["local_maps_shipped"] > 0 and s["local_maps_acknowledged"] == s["local_maps_shipped"], path
    names = set(s["processes"])
    for expected in ("lmf-server", "lmf-agent0", "lmf-agent2", "lmf-player", "lmf-monitor", "lcm-logger"):
        assert expected in names, f"{path}: no samples of {expected} ({sorted(names)})"
    for name, p in s["processes"].items():
        assert p["samples"] >= 2 and p["rss_end_mb"] > 0, f"{path}: {name} {p}"
    print(f"{path}: passed, {s['local_maps_shipped']} local maps acknowledged, {len(names)} processes sampled")
assert json.load(open(sys.argv[1]))["trajectories_vs_offline_rmse_m"] is not None
assert json.load(open(sys.argv[2]))["loss"] == 0.1
PY
