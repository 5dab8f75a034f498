# shellcheck shell=bash
# Private network namespaces for running lmf processes over LCM multicast on
# one machine (docs/design.md §7) without a single packet reaching a real network.
#
# Source this file, then:
#   lmf_netns_supported            # exit status 0 if a namespace can be made here
#   lmf_netns_exec CMD [ARGS...]   # run CMD inside a fresh private namespace
#   lmf_netns_url                  # the LCM URL used inside: loopback multicast, ttl=0
#
# Inside the namespace (what lmf_netns_exec sets up before exec'ing CMD):
#   * the only interface is `lo`, brought up, with 224.0.0.0/4 routed to it, so
#     LCM's UDP multicast loops back between the processes of the namespace;
#   * LCM_DEFAULT_URL=udpm://239.255.76.67:7667?ttl=0 is exported, so every lmf
#     process and lcm-logger/lcm-spy there use it without flags;
#   * the namespace also has its own PID namespace (and a private /proc for
#     it, so ps and sanitizers see the right processes): when CMD exits (or the
#     `unshare` running it is killed) every process started inside is killed,
#     so a test that times out leaves nothing behind.
# The namespace is created with `unshare -rn` (an unprivileged user namespace;
# works for root and non-root where user namespaces are allowed), falling back
# to `unshare -n` for root when user namespaces are disabled. Named `ip netns`
# namespaces are not used: they outlive a crashed test.
#
# Safety: lmf_netns_setup refuses to continue (exit status 3) unless the
# current namespace has no interface but `lo`, so nothing run through these
# functions can send multicast on the host network.
#
# Example:
#   source scripts/lib/netns.sh
#   lmf_netns_exec bash -c 'lcm-logger -q out.log & lmf-player ...; kill %1'

LMF_NETNS_LIB="${BASH_SOURCE[0]}"
LMF_NETNS_URL='udpm://239.255.76.67:7667?ttl=0'

lmf_netns_url() { printf '%s\n' "$LMF_NETNS_URL"; }

# The unshare flags that work here (printed), or status 1 if none does.
lmf_netns_unshare_flags() {
  local flags
  for flags in "-rn --pid --fork --kill-child --mount-proc" "-n --pid --fork --kill-child --mount-proc"; do
    # shellcheck disable=SC2086
    if unshare $flags true >/dev/null 2>&1; then
      printf '%s\n' "$flags"
      return 0
    fi
  done
  return 1
}

lmf_netns_supported() {
  command -v unshare >/dev/null 2>&1 && command -v ip >/dev/null 2>&1 && lmf_netns_unshare_flags >/dev/null
}

# True if the current network namespace has no interface other than lo.
lmf_netns_is_private() {
  local names
  names=$(ip -o link show 2>/dev/null | awk -F': ' '{ sub(/@.*/, "", $2); print $2 }') || return 1
  [[ -n "$names" && "$names" == "lo" ]]
}

# Run inside a fresh namespace: loopback up, multicast routed to it, LCM URL set.
lmf_netns_setup() {
  if ! lmf_netns_is_private; then
    echo "lmf_netns_setup: refusing: this network namespace has interfaces besides lo" >&2
    return 3
  fi
  ip link set lo up || return 3
  ip route add 224.0.0.0/4 dev lo 2>/dev/null || ip route replace 224.0.0.0/4 dev lo || return 3
  export LCM_DEFAULT_URL="$LMF_NETNS_URL"
}

# Runs CMD ARGS... in a new private network (and PID) namespace; returns its
# exit status (3 if the namespace could not be set up, 4 if none can be made).
lmf_netns_exec() {
  local flags
  if ! flags=$(lmf_netns_unshare_flags); then
    echo "lmf_netns_exec: cannot create a network namespace here (unshare -rn / -n refused)" >&2
    return 4
  fi
  # shellcheck disable=SC2086,SC2016
  unshare $flags bash -c 'source "$0" && lmf_netns_setup || exit 3; exec "$@"' "$LMF_NETNS_LIB" "$@"
}
