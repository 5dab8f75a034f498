#!/usr/bin/env bash
# Installs every Debian package lmf needs. Idempotent: quiet when all are present,
# and runs `apt-get update` only when something is missing.
set -euo pipefail

packages=(
  build-essential cmake ninja-build pkg-config git
  ccache  # scripts/build.sh: a compiler cache that clones in other folders share
  liblcm-dev liblcm-bin
  libeigen3-dev
  libboost-dev libboost-program-options-dev
  nlohmann-json3-dev
  zlib1g-dev
  librosbag-storage-dev libboost-filesystem-dev  # lmf/bag: ROS 1 bags through ROS's own library
  libbz2-dev libzstd-dev liblz4-dev libsqlite3-dev  # lmf/bag: ROS 1 and MCAP chunks, rosbag2's SQLite3
  libssl-dev
  libgtest-dev libgmock-dev
  libbenchmark-dev
  iproute2 util-linux
  dpkg-dev file  # cpack -G DEB (tests/install): dpkg-shlibdeps, file
)
# --fuzz: also clang and its libFuzzer runtime, for the optional libFuzzer
# build of tests/fuzz (scripts/fuzz.sh --libfuzzer); lmf-fuzz needs neither.
if [[ "${1:-}" == --fuzz ]]; then packages+=(clang-14 libclang-rt-14-dev); fi

missing=()
for p in "${packages[@]}"; do
  status=$(dpkg-query -W -f='${Status}' "$p" 2>/dev/null || true)
  [[ "$status" == "install ok installed" ]] || missing+=("$p")
done
[[ ${#missing[@]} -eq 0 ]] && exit 0

echo "install-deps: installing ${missing[*]}"
sudo_cmd=()
[[ $(id -u) -eq 0 ]] || sudo_cmd=(sudo)
export DEBIAN_FRONTEND=noninteractive
"${sudo_cmd[@]}" apt-get update -qq
"${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
echo "install-deps: done"
