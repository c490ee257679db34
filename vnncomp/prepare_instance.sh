#!/usr/bin/env bash
# VNN-COMP tool interface: prepare_instance.sh v1 CATEGORY ONNX VNNLIB
# Builds the release binary if it is missing (or uses $SAMARA_BIN) and checks that the
# instance loads (the network's operators, the property's syntax): exit 0 when it is ready,
# non-zero otherwise (the message on stderr names the file, line or operator).
set -euo pipefail
if [ "$#" -ne 4 ] || [ "$1" != "v1" ]; then
  echo "usage: $0 v1 CATEGORY ONNX VNNLIB" >&2
  exit 1
fi
here="$(cd "$(dirname "$0")" && pwd)"
repo="$(dirname "$here")"
bin="${SAMARA_BIN:-$repo/target/release/samara}"
if [ ! -x "$bin" ]; then
  (cd "$repo" && cargo build --release -q -p samara-cli) >&2
fi
onnx="$3"
vnnlib="$4"
# Competition harnesses may hand over gzipped files.
for f in "$onnx" "$vnnlib"; do
  if [ ! -f "$f" ] && [ -f "$f.gz" ]; then gunzip -kf "$f.gz"; fi
done
# Load and check only (time limit 0: nothing is searched).
set +e
msg="$("$bin" verify-vnnlib --network "$onnx" --property "$vnnlib" --timeout 0 2>&1 >/dev/null)"
code=$?
set -e
if [ "$code" -eq 2 ]; then
  echo "$msg" >&2
  echo "prepare_instance: $2 $onnx $vnnlib: not supported (see the message above)" >&2
  exit 1
fi
exit 0
