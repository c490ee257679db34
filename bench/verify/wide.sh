#!/usr/bin/env bash
# P1-P4 critical values of the wide 6-64-32-1 controllers (crates/samara-verify/tests/data/wide)
# by `samara critical` (exact, sound) beside the HiGHS big-M MILP (samara_verify::milp, a
# floating-point cross-check), with times. Needs cmake and libclang-dev for the HiGHS build
# (apt-get install -y cmake libclang-dev). Release builds. Output: a markdown table on stdout.
# Usage: bench/verify/wide.sh [NET.onnx ...]   (default: the paper's goedel_lipschitz_norm.onnx and
# the two samara-trained wide networks; bench/verify/gen_lipschitz.sh makes more of the paper's kind)
set -euo pipefail
repo="$(cd "$(dirname "$0")/../.." && pwd)"
cd "$repo"
nets=("$@")
if [ "${#nets[@]}" -eq 0 ]; then
  nets=(../shared/reference/goedel_lipschitz_norm.onnx crates/samara-verify/tests/data/wide/dl2_6_64_32_1.onnx crates/samara-verify/tests/data/wide/goedel_6_64_32_1.onnx)
fi
cargo build --release -q -p samara-cli
cargo build --release -q -p samara-verify --features highs --example wide_milp
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
# The spec in raw units: these networks carry their own normalisation layers.
awk 'skip && prev ~ /\\$/ {prev=$0; next} {skip=0} /^normalise f/ {skip=1; prev=$0; next} {print}' \
  models/alsomitra/alsomitra.spec > "$tmp/raw.spec"
echo "| network | property | samara critical | complete | samara s | HiGHS value | HiGHS s | samara engine (same queries) s |"
echo "|---|---|---|---|---|---|---|---|"
target/release/examples/wide_milp "${nets[@]}" > "$tmp/milp.csv"
for n in "${nets[@]}"; do
  stem="$(basename "$n" .onnx)"
  for p in 1 2 3 4; do
    set +e
    # *_norm.onnx networks take normalised inputs (the published convention): the
    # shipped spec with its normalise lines; the others carry their own normalisation.
    s="$tmp/raw.spec"
    case "$stem" in *_norm) s="$repo/models/alsomitra/alsomitra.spec" ;; esac
    j="$(target/release/samara critical "$s" --property "p$p" --param ystar --network "f=$n" --timeout 600 --json)"
    set -e
    crit="$(python3 -c 'import json,sys; d=json.loads(sys.argv[1]); print(d.get("critical"), d.get("complete"), "%.2f" % d.get("seconds", float("nan")))' "$j")"
    read -r value complete secs <<< "$crit"
    milp="$(awk -F, -v s="$stem" -v p="P$p" 'tolower($1)==tolower(s) && toupper($2)==p {print $7, $8, $6}' "$tmp/milp.csv")"
    read -r hv hs es <<< "${milp:-- - -}"
    echo "| $stem | P$p | $value | $complete | $secs | $hv | $hs | $es |"
  done
done
