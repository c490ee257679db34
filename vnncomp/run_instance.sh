#!/usr/bin/env bash
# VNN-COMP tool interface: run_instance.sh v1 CATEGORY ONNX VNNLIB RESULTS_FILE TIMEOUT
# Writes RESULTS_FILE in the competition format (`unsat`, `timeout`, `unknown`, or `sat`
# and the assignment ((X_0 v) ... (Y_m v)), one variable per line). Samara's own time limit
# is 95 % of TIMEOUT (the harness's clock also counts loading). Exit 0 whenever a verdict
# was written; non-zero on bad input (no result file then: the harness records an error).
set -euo pipefail
if [ "$#" -ne 6 ] || [ "$1" != "v1" ]; then
  echo "usage: $0 v1 CATEGORY ONNX VNNLIB RESULTS_FILE TIMEOUT" >&2
  exit 1
fi
here="$(cd "$(dirname "$0")" && pwd)"
repo="$(dirname "$here")"
bin="${SAMARA_BIN:-$repo/target/release/samara}"
if [ ! -x "$bin" ]; then
  echo "run_instance: $bin not built; run prepare_instance.sh first (or set SAMARA_BIN)" >&2
  exit 1
fi
onnx="$3"
vnnlib="$4"
results="$5"
limit="$(awk -v t="$6" 'BEGIN { if (t + 0 <= 0) print 0; else printf "%.3f", 0.95 * t }')"
set +e
"$bin" verify-vnnlib --network "$onnx" --property "$vnnlib" --timeout "$limit" --result "$results"
code=$?
set -e
# 0 unsat, 1 sat/timeout/unknown (the file says which), 2 bad input.
if [ "$code" -eq 0 ] || [ "$code" -eq 1 ]; then
  exit 0
fi
exit "$code"
