#!/usr/bin/env bash
# The real lmf-agent (x2) and lmf-player binaries over UDP multicast inside a
# private network namespace (scripts/lib/netns.sh), no server: the player
# replays an lmf-sim folder in lockstep, the agents ack every scan, then get
# mission_end_t (sent once the unanswered sightings are given up after
# --end-wait-ms) and are stopped with SIGTERM.
# Usage: player_netns.sh AGENT PLAYER SIM_DIR
# Exit: 0 passed, 77 namespaces not permitted here (skip), other: failure.
set -u
agent=$1 player=$2 sim=$3
root=$(cd "$(dirname "$0")/../.." && pwd)
# shellcheck source=../../scripts/lib/netns.sh
source "$root/scripts/lib/netns.sh"
if ! lmf_netns_supported; then
  echo "SKIP: cannot create a private network namespace (unshare -rn refused)"
  exit 77
fi
# shellcheck disable=SC2016
lmf_netns_exec bash -c '
  agent=$1 player=$2 sim=$3
  echo "inside: $(ip -o link | wc -l) interface(s), LCM_DEFAULT_URL=$LCM_DEFAULT_URL"
  "$agent" --robot-id 0 --resend-interval-ms 200 & a0=$!
  "$agent" --robot-id 1 --resend-interval-ms 200 & a1=$!
  "$player" --sim "$sim" --lockstep --ack-timeout-ms 500 --end-wait-ms 3000 --start-delay-ms 300 --quiet; player_rc=$?
  sleep 0.3
  kill -TERM "$a0" "$a1"
  wait "$a0"; a0_rc=$?
  wait "$a1"; a1_rc=$?
  echo "player exit $player_rc, agent exits $a0_rc $a1_rc"
  [[ $player_rc -eq 0 && $a0_rc -eq 0 && $a1_rc -eq 0 ]]' _ "$agent" "$player" "$sim"
