#!/usr/bin/env bash
# Every development dataset (noisy and realodo), converted by lmf-convert to a
# ROS 1 bag (lz4 chunks) and to MCAP (zstd chunks), maps with lmf-offline --bag
# exactly as with --log: the same trajectory.txt and map.json, byte for byte
# (two robots, --split 2). Exit 77 (skipped) without ../shared/datasets.
#   bags_match_logs.sh BUILD_DIR
set -euo pipefail
build=$1
datasets=${LMF_DATASETS_DIR:-}
if [[ -z "$datasets" || ! -d "$datasets" ]]; then
  echo "SKIP: shared datasets folder not found (LMF_DATASETS_DIR=$datasets)"
  exit 77
fi
work=$(mktemp -d "${TMPDIR:-/tmp}/lmf-bags-match-logs.XXXXXX")
trap 'rm -rf "$work"' EXIT
status=0 compared=0
for log in "$datasets"/*-noisy.log.gz "$datasets"/*-realodo.log.gz; do
  [[ -e "$log" ]] || continue
  name=$(basename "$log" .log.gz)
  gt=$datasets/$name.gt
  "$build/tools/lmf-offline" --log "$log" --split 2 --gt "$gt" --out "$work/$name-log" >/dev/null
  for kind in "bag lz4" "mcap zstd"; do
    read -r ext compression <<<"$kind"
    "$build/tools/lmf-convert" --log "$log" --out "$work/$name.$ext" --compression "$compression" >/dev/null
    "$build/tools/lmf-offline" --bag "$work/$name.$ext" --split 2 --gt "$gt" --out "$work/$name-$ext" >/dev/null
    for file in trajectory.txt map.json; do
      if cmp -s "$work/$name-log/$file" "$work/$name-$ext/$file"; then
        echo "$name: .$ext ($compression) gives the log's $file"
      else
        echo "FAIL: $name: .$ext ($compression) gives another $file than the log"
        status=1
      fi
    done
    rm -f "$work/$name.$ext"
    compared=$((compared + 1))
  done
done
if [[ $compared -eq 0 ]]; then echo "SKIP: no *-noisy/*-realodo logs in $datasets"; exit 77; fi
exit $status
