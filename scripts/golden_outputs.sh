#!/usr/bin/env bash
# Capture the `--json` outputs, exit codes and written files of the commands whose
# results issue 38 moves into typed library values, so that a refactoring can be
# checked byte for byte:
#
#   scripts/golden_outputs.sh /tmp/golden-before          # with the old binary
#   ... change the code, cargo build --release -p samara-cli ...
#   scripts/golden_outputs.sh /tmp/golden-after
#   scripts/golden_outputs.sh --compare /tmp/golden-before /tmp/golden-after
#
# Run from the repository root. SAMARA (default target/release/samara) is the binary,
# REF (default ../shared/reference) the published reference files. One worker thread
# (RAYON_NUM_THREADS=1, --threads 1) so that parallel searches find the same
# counterexample on every run.
#
# The comparison masks only what differs between any two runs: wall times (the JSON
# fields `seconds`, `total_seconds`, `elapsed_s` and `wall_seconds` at any depth, the `seconds` column
# of results CSVs, numbers followed by ` s` or `s` in human text), the shard files'
# `digest` (their seal, a hash over content that includes the wall times) and the
# output folder's own path (replaced by <OUT>). Everything else must be identical.
set -euo pipefail

if [[ "${1:-}" == "--compare" ]]; then
    [[ $# -eq 3 ]] || { echo "usage: $0 --compare BEFORE AFTER" >&2; exit 2; }
    exec python3 - "$2" "$3" <<'PY'
import json, os, re, sys
KEYS = re.compile(r'("(?:seconds|total_seconds|elapsed_s|wall_seconds|digest)"\s*:\s*)("[^"]*"|[-0-9.eE+]+|null)')
def masked(path, root):
    data = open(path, "rb").read().replace(os.path.abspath(root).encode(), b"<OUT>")
    name = os.path.basename(path)
    try:
        text = data.decode()
    except UnicodeDecodeError:
        return data
    # The text stays as written (layout included); only the masked values change.
    text = KEYS.sub(r"\1<masked>", text)
    if name.endswith(".csv") and text.startswith("onnx,vnnlib,timeout,result,seconds"):
        lines = [l.split(",") for l in text.splitlines()]
        return "\n".join(",".join(f if i != 4 else "<time>" for i, f in enumerate(l)) for l in lines)
    return re.sub(r"[0-9.]+(e-?[0-9]+)? ?s\b", "<time> s", text)
def files(root):
    out = {}
    for d, _, fs in os.walk(root):
        for f in fs:
            p = os.path.join(d, f)
            out[os.path.relpath(p, root)] = p
    return out
a, b = files(sys.argv[1]), files(sys.argv[2])
bad = 0
for k in sorted(set(a) | set(b)):
    if k not in a or k not in b:
        print(f"only in {'before' if k in a else 'after'}: {k}"); bad += 1; continue
    if masked(a[k], sys.argv[1]) != masked(b[k], sys.argv[2]):
        print(f"differs: {k}"); bad += 1
print(f"{len(set(a) | set(b))} files compared, {bad} differ")
sys.exit(1 if bad else 0)
PY
fi

[[ $# -eq 1 ]] || { echo "usage: $0 OUTDIR | $0 --compare BEFORE AFTER" >&2; exit 2; }
OUT=$1
BIN=${SAMARA:-target/release/samara}
REF=${REF:-../shared/reference}
SPEC=models/alsomitra/alsomitra.spec
ACAS=crates/samara-verify/tests/data/acasxu
export RAYON_NUM_THREADS=1
[[ -x $BIN ]] || { echo "$BIN: no such binary (cargo build --release -p samara-cli)" >&2; exit 2; }
[[ -f $REF/base_model_norm.onnx ]] || { echo "$REF/base_model_norm.onnx: not found (set REF)" >&2; exit 2; }
mkdir -p "$OUT"
if [[ -n "$(ls -A "$OUT")" ]]; then echo "$OUT: not empty" >&2; exit 2; fi

# run NAME ARGS...: stdout to NAME.stdout, stderr to NAME.stderr, exit code to NAME.rc.
run() {
    local name=$1; shift
    local rc=0
    "$BIN" "$@" >"$OUT/$name.stdout" 2>"$OUT/$name.stderr" || rc=$?
    echo "$rc" >"$OUT/$name.rc"
    echo "$name: exit $rc" >&2
}

NET=$REF/base_model_norm.onnx
DATA=$REF/Training_Data_Normalised.csv
run verify verify "$SPEC" --network "f=$NET" --json
for p in p1 p2 p3 p4; do
    run "critical_$p" critical "$SPEC" --network "f=$NET" --property "$p" --param ystar --json
done
# A small robustness table: the first 12 training points, written per point.
head -n 13 "$DATA" >"$OUT/robustness_data.csv"
run robustness robustness --network "$NET" --data "$OUT/robustness_data.csv" \
    --eps 1e-4,1e-3 --lipschitz 1e-5,1e-3,1e-2 --json --out "$OUT/robustness_points.csv"
for i in 0 1; do
    run "robustness_shard$i" robustness --network "$NET" --data "$OUT/robustness_data.csv" \
        --eps 1e-4,1e-3 --lipschitz 1e-5,1e-3,1e-2 --shard "$i/2" --out "$OUT/robustness_shard$i.json"
done
run robustness_merge merge robustness "$OUT/robustness_shard0.json" "$OUT/robustness_shard1.json" \
    --json --out "$OUT/robustness_merged.csv"
# VNN-COMP: four ACAS Xu instances (three unsat, one sat).
printf '%s\n' \
    "ACASXU_run2a_1_1_batch_2000.onnx,prop_1.vnnlib,116" \
    "ACASXU_run2a_1_2_batch_2000.onnx,prop_1.vnnlib,116" \
    "ACASXU_run2a_1_1_batch_2000.onnx,prop_2.vnnlib,116" \
    "ACASXU_run2a_1_2_batch_2000.onnx,prop_2.vnnlib,116" >"$OUT/instances.csv"
run vnncomp vnncomp "$OUT/instances.csv" --root "$ACAS" --out "$OUT/vnncomp_results.csv" --json
for i in 0 1; do
    run "vnncomp_shard$i" vnncomp "$OUT/instances.csv" --root "$ACAS" --shard "$i/2" \
        --out "$OUT/vnncomp_shard$i.json"
done
run vnncomp_merge merge vnncomp "$OUT/vnncomp_shard0.json" "$OUT/vnncomp_shard1.json" \
    --out "$OUT/vnncomp_merged.csv" --json
run verify_vnnlib verify-vnnlib --network "$ACAS/ACASXU_run2a_1_2_batch_2000.onnx" \
    --property "$ACAS/prop_2.vnnlib" --result "$OUT/verify_vnnlib_result.txt" --json
# Reach: the published setting (raw-unit controller, defaults), its shards, and one
# system file.
DENORM=$REF/base_model_denorm.onnx
run reach reach --network "$DENORM" --threads 1 --json --out "$OUT/reach"
for i in 0 1; do
    run "reach_shard$i" reach --network "$DENORM" --threads 1 --shard "$i/2" \
        --out "$OUT/reach_shard$i.json"
done
run reach_merge merge reach "$OUT/reach_shard0.json" "$OUT/reach_shard1.json" \
    --json --out "$OUT/reach_merged"
run reach_system reach --system examples/archcomp/acc.sys \
    --network crates/samara-reach/tests/data/archcomp/controller_acc_5_20.onnx \
    --threads 1 --json --out "$OUT/reach_system"
# The same system on a two-cell grid, sharded (Taylor-model shards) and merged.
run reach_system_shard0 reach --system examples/archcomp/acc.sys \
    --network crates/samara-reach/tests/data/archcomp/controller_acc_5_20.onnx \
    --threads 1 --grid x_lead=2 --shard 0/2 --json --out "$OUT/reach_system_shard0.json"
run reach_system_shard1 reach --system examples/archcomp/acc.sys \
    --network crates/samara-reach/tests/data/archcomp/controller_acc_5_20.onnx \
    --threads 1 --grid x_lead=2 --shard 1/2 --out "$OUT/reach_system_shard1.json"
run reach_system_merge merge reach "$OUT/reach_system_shard0.json" \
    "$OUT/reach_system_shard1.json" --json --out "$OUT/reach_system_merged"
# Simulate (the built-in glider under a constant controller, and a system file under
# its network) and train (a small plain run whose first seed restarts).
run simulate simulate --controller constant:0.187 --y0 2,3 --horizon 10 --no-plot \
    --out "$OUT/simulate" --json
run simulate_human simulate --controller constant:0.187 --y0 2 --horizon 5 --no-plot \
    --out "$OUT/simulate_human"
run simulate_system simulate --system examples/archcomp/acc.sys \
    --controller crates/samara-reach/tests/data/archcomp/controller_acc_5_20.onnx \
    --out "$OUT/simulate_system" --json
head -n 301 "$REF/Training_Data.csv" >"$OUT/train_data.csv"
run train train --data "$OUT/train_data.csv" --epochs 20 --seed 1 --min-r2 0 \
    --out "$OUT/train.onnx" --json
run train_human train --data "$OUT/train_data.csv" --epochs 5 --seed 2 --min-r2 0 \
    --out "$OUT/train_human.onnx"
echo "wrote $OUT" >&2
