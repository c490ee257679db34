#!/usr/bin/env bash
# Creates bench/.venv with the Python peers samara is benchmarked and cross-checked
# against (scipy, torch CPU, onnx, onnxruntime, maraboupy, highspy). Idempotent.
# Usage: bench/setup_venv.sh   (then bench/.venv/bin/python ...)
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
venv="$here/.venv"
if [ ! -x "$venv/bin/python" ]; then
  python3 -m venv "$venv"
fi
"$venv/bin/pip" install -q --upgrade pip
"$venv/bin/pip" install -q -r "$here/requirements.txt"
# torch from the CPU-only index when reachable, else PyPI.
if [ "${SAMARA_BENCH_TORCH:-1}" = "1" ]; then
  "$venv/bin/pip" install -q torch --index-url https://download.pytorch.org/whl/cpu 2>/dev/null \
    || "$venv/bin/pip" install -q torch
fi
echo "venv ready: $venv"
