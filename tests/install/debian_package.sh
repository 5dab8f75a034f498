#!/usr/bin/env bash
# `cpack -G DEB` in the build tree: lmf (programs, configs) and lmf-dev
# (libraries, headers, CMake package) with their Depends; the programs of the
# unpacked lmf run (--help, and a short simulated mission with the packaged config).
#   debian_package.sh BUILD_DIR VERSION
set -euo pipefail
build=$1 version=$2
command -v dpkg-deb >/dev/null || { echo "SKIP: no dpkg-deb"; exit 77; }
command -v dpkg-shlibdeps >/dev/null || { echo "SKIP: no dpkg-shlibdeps (Debian package dpkg-dev)"; exit 77; }
work=$(mktemp -d)
[[ -n ${LMF_TEST_KEEP:-} ]] && echo "keeping $work" || trap 'rm -rf "$work"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

(cd "$work" && cpack -G DEB --config "$build/CPackConfig.cmake" -B "$work/pkg") >"$work/cpack.log" 2>&1 ||
  { cat "$work/cpack.log"; fail "cpack -G DEB"; }
arch=$(dpkg --print-architecture)
runtime=$work/pkg/lmf_${version}_${arch}.deb
dev=$work/pkg/lmf-dev_${version}_${arch}.deb
[[ -f $runtime && -f $dev ]] || { ls "$work/pkg"; fail "expected lmf_${version}_${arch}.deb and lmf-dev_${version}_${arch}.deb"; }
ls -l "$runtime" "$dev" | awk '{print $5, $9}'

# Depends: what the programs link (dpkg-shlibdeps), and lmf-dev on lmf and the -dev packages.
depends=$(dpkg-deb -f "$runtime" Depends)
echo "lmf Depends: $depends"
for p in liblcm1 libboost-program-options zlib1g libssl libstdc++6 libc6; do
  grep -q "$p" <<<"$depends" || fail "lmf does not depend on $p"
done
dev_depends=$(dpkg-deb -f "$dev" Depends)
echo "lmf-dev Depends: $dev_depends"
for p in "lmf (= $version)" liblcm-dev libeigen3-dev nlohmann-json3-dev; do
  grep -qF "$p" <<<"$dev_depends" || fail "lmf-dev does not depend on $p"
done

contents=$(dpkg-deb -c "$runtime")
for f in bin/lmf-server bin/lmf-agent bin/lmf-player bin/lmf-monitor bin/lmf-offline bin/lmf-sim \
         share/lmf/config/default.json share/lmf/config/sim.json; do
  grep -q "\./usr/$f\$" <<<"$contents" || fail "lmf lacks /usr/$f"
done
if [[ -f $build/lcmtypes/lmf-types.jar ]]; then  # built where a JDK and liblcm-java are
  grep -q "\./usr/share/java/lmf-types.jar\$" <<<"$contents" || fail "lmf lacks /usr/share/java/lmf-types.jar"
fi
dev_contents=$(dpkg-deb -c "$dev")
for f in lib/cmake/lmf/lmfConfig.cmake lib/liblmf_local_map.a include/lmf/local_map/local_map.hpp \
         include/lmf/pose2_t.hpp; do
  grep -q "\./usr/$f\$" <<<"$dev_contents" || fail "lmf-dev lacks /usr/$f"
done

root=$work/root
dpkg-deb -x "$runtime" "$root"
help=$("$root/usr/bin/lmf-offline" --help) || fail "lmf-offline --help exited with $?"
grep -q "^Usage: lmf-offline" <<<"$help" || fail "lmf-offline --help: no usage line"
for program in lmf-server lmf-agent lmf-player lmf-monitor lmf-sim lmf-score; do
  "$root/usr/bin/$program" --help >/dev/null || fail "$program --help exited with $?"
done
"$root/usr/bin/lmf-sim" --robots 2 --seed 3 --duration-s 40 --out "$work/sim" >/dev/null
"$root/usr/bin/lmf-offline" --sim "$work/sim" --config "$root/usr/share/lmf/config/sim.json" --out "$work/out" \
  >"$work/offline.log" || { cat "$work/offline.log"; fail "lmf-offline from the package"; }
[[ -s $work/out/map.json && -s $work/out/trajectory.txt ]] || fail "lmf-offline from the package wrote no map"
echo "PASS: $(basename "$runtime") and $(basename "$dev")"
