#!/usr/bin/env bash
# scripts/accuracy.sh --smoke (one dataset case where the datasets exist, one short simulated
# mission) exits 0 and its --json output parses with the expected keys.
# Usage: accuracy_smoke.sh BUILD_DIR SOURCE_DIR
set -euo pipefail
build=$1 source=$2
out=$(mktemp -d "${TMPDIR:-/tmp}/lmf-accuracy-smoke.XXXXXX")
trap 'rm -rf "$out"' EXIT
BUILD_DIR=$build timeout 300 bash "$source/scripts/accuracy.sh" --smoke --json "$out/accuracy.json" \
  --markdown "$out/accuracy.md"
"$build/tests/system/accuracy-json-check" "$out/accuracy.json" 1
grep -q '^| case |' "$out/accuracy.md"
