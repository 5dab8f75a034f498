#!/usr/bin/env bash
# One "machine" of scripts/multihost.sh: runs as the first process of a fresh
# network namespace (`unshare -n`, nested inside the private outer namespace of
# scripts/lib/multihost-mission.sh). It waits until the outer namespace has
# moved the far end of a veth pair in here as `eth0`, configures it the way a
# user configures a real machine for LCM multicast (address, link up,
# 224.0.0.0/4 routed to it, ttl=1), writes READY_FILE ("IP NETNS"), runs CMD
# (SIGTERM/SIGINT to this PID are passed on to it), and when CMD has exited
# writes READY_FILE.traffic ("SENT_BYTES RECEIVED_BYTES" over eth0) and exits
# with CMD's status; the namespace dies with this process.
#   multihost-node.sh ADDRESS/PREFIX READY_FILE CMD [ARGS...]
set -euo pipefail
address=$1 ready=$2
shift 2

# Never configure anything in a namespace that already has interfaces: this
# one must be fresh (lo only) until the outer namespace hands us eth0.
names=$(ip -o link show | awk -F': ' '{ sub(/@.*/, "", $2); print $2 }' | sort | tr '\n' ' ')
for _ in $(seq 200); do
  [[ $names == "eth0 lo " ]] && break
  if [[ $names != "lo " ]]; then
    echo "multihost-node: refusing: unexpected interfaces here: $names" >&2
    exit 3
  fi
  sleep 0.05
  names=$(ip -o link show | awk -F': ' '{ sub(/@.*/, "", $2); print $2 }' | sort | tr '\n' ' ')
done
[[ $names == "eth0 lo " ]] || { echo "multihost-node: eth0 never arrived" >&2; exit 3; }

ip link set lo up
ip addr add "$address" dev eth0
ip link set eth0 up
ip route add 224.0.0.0/4 dev eth0
export LCM_DEFAULT_URL='udpm://239.255.76.67:7667?ttl=1'
printf '%s %s\n' "${address%/*}" "$(readlink /proc/self/ns/net)" >"$ready.tmp"
mv "$ready.tmp" "$ready"
"$@" &
child=$!
trap 'kill -TERM "$child" 2>/dev/null || true' TERM INT
status=0
while kill -0 "$child" 2>/dev/null; do
  status=0
  wait "$child" || status=$?
done
# /proc/net/dev is this namespace's (sysfs would be the mounter's).
awk -F'[: ]+' '$2 == "eth0" { print $11, $3 }' /proc/net/dev >"$ready.traffic"
exit "$status"
