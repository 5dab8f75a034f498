#!/usr/bin/env bash
# Passes LCM messages between two processes inside a private network namespace
# (scripts/lib/netns.sh). Usage: netns_pingpong.sh PEER_BINARY
# Exit: 0 passed, 77 namespaces not permitted here (skip), other: failure.
set -u
peer=$1
root=$(cd "$(dirname "$0")/../.." && pwd)
# shellcheck source=../../scripts/lib/netns.sh
source "$root/scripts/lib/netns.sh"
if ! lmf_netns_supported; then
  echo "SKIP: cannot create a private network namespace (unshare -rn refused)"
  exit 77
fi
# shellcheck disable=SC2016
lmf_netns_exec bash -c '
  peer=$1
  echo "inside: $(ip -o link | wc -l) interface(s), LCM_DEFAULT_URL=$LCM_DEFAULT_URL"
  "$peer" --role echo --timeout-ms 8000 & echo_pid=$!
  "$peer" --role ping --timeout-ms 8000; ping_rc=$?
  wait "$echo_pid"; echo_rc=$?
  echo "ping exit $ping_rc, echo exit $echo_rc"
  [[ $ping_rc -eq 0 && $echo_rc -eq 0 ]]' _ "$peer"
