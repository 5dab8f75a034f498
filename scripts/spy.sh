#!/usr/bin/env bash
# lcm-spy with lmf's message types (lmf-types.jar, built when a JDK and
# liblcm-java are installed), so every LMF_* channel is decoded field by field.
#   scripts/spy.sh --log FILE [--speed S]   replay an lcm-logger capture (e.g. the demo's OUT/lmf.lcmlog)
#                                           with lcm-logplayer and spy on it, both inside one fresh
#                                           private network namespace (nothing leaves the machine)
#   scripts/spy.sh -- CMD [ARGS...]         run CMD (e.g. scripts/lib/run-mission.sh ...) and lcm-spy
#                                           together inside one fresh private network namespace
#   scripts/spy.sh --lcm-url URL            spy on the bus you name (e.g. the robots' network:
#                                           udpm://239.255.76.67:7667?ttl=1); nothing else is started
# lcm-spy is a Swing window: it needs a display (DISPLAY or WAYLAND_DISPLAY).
# BUILD_DIR: the build tree holding lcmtypes/lmf-types.jar (default build/);
# LMF_TYPES_JAR overrides the jar (e.g. /usr/share/java/lmf-types.jar of the lmf package).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${BUILD_DIR:-$root/build}
usage() { sed -n '2,14p' "$0" | sed 's/^# \{0,1\}//' >&2; exit 2; }

mode= log= speed=1 url= command=()
while [[ $# -gt 0 ]]; do
  case $1 in
    --log) mode=log log=${2:?--log needs a file}; shift 2 ;;
    --speed) speed=${2:?--speed needs a value}; shift 2 ;;
    --lcm-url) mode=url url=${2:?--lcm-url needs a URL}; shift 2 ;;
    --) shift; mode=command command=("$@"); [[ ${#command[@]} -gt 0 ]] || usage; break ;;
    -h|--help) usage ;;
    *) echo "spy.sh: unknown argument $1" >&2; usage ;;
  esac
done
[[ -n $mode ]] || usage

jar=${LMF_TYPES_JAR:-$build/lcmtypes/lmf-types.jar}
lcm_jar=/usr/share/java/lcm.jar
[[ -f $jar ]] || { echo "spy.sh: no $jar: install default-jdk-headless and liblcm-java, then rebuild (cmake says why it did not build it)" >&2; exit 1; }
[[ -f $lcm_jar ]] || { echo "spy.sh: no $lcm_jar (Debian: liblcm-java)" >&2; exit 1; }
command -v java >/dev/null || { echo "spy.sh: no java (Debian: default-jre)" >&2; exit 1; }
if [[ -z ${DISPLAY:-} && -z ${WAYLAND_DISPLAY:-} ]]; then
  echo "spy.sh: lcm-spy opens a window, and there is no display (DISPLAY / WAYLAND_DISPLAY unset)" >&2
  exit 1
fi
# Debian's /usr/bin/lcm-spy passes -Xincgc, which Java 9 and later refuse: start lcm.spy.Spy directly.
classpath=$lcm_jar:$jar
[[ -f /usr/share/java/jchart2d.jar ]] && classpath=$classpath:/usr/share/java/jchart2d.jar  # its plots (libjchart2d-java)
spy=(java -Djava.net.preferIPv4Stack=true -Xmx256m -cp "$classpath" lcm.spy.Spy)

case $mode in
  url) exec "${spy[@]}" --lcm-url="$url" ;;
  log|command)
    source "$root/scripts/lib/netns.sh"
    lmf_netns_supported || { echo "spy.sh: cannot create a private network namespace here (unshare -rn)" >&2; exit 1; }
    if [[ $mode == log ]]; then
      [[ -f $log ]] || { echo "spy.sh: no capture $log" >&2; exit 1; }
      command=(lcm-logplayer --speed="$speed" "$log")
    fi
    # Inside: spy in the background on the namespace's LCM_DEFAULT_URL, the command in front;
    # when the command ends, spy stays open until its window is closed.
    # shellcheck disable=SC2016
    lmf_netns_exec bash -c '"${@:2:$1}" & spy=$!; sleep 1; "${@:$(($1 + 2))}"; wait $spy' _ \
      "${#spy[@]}" "${spy[@]}" "${command[@]}"
    ;;
esac
