#!/usr/bin/env bash
# Capture the outputs (stdout and stderr, `--json` and human), exit codes and written
# files of every command, and the messages of refused inputs, so that a refactoring can
# be checked byte for byte (docs/architecture.md, "Checking a refactoring byte for
# byte"):
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
# fields `elapsed_s` and any ending in `seconds` at any depth, the `seconds` column of
# results CSVs, the time columns of closed-loop training's rounds log, and numbers
# followed by ` s` or `s` in human text, with the spaces that pad them), the shard
# files' `digest` (their seal, a hash over content that includes the wall times) and
# the output folder's own path (replaced by <OUT>). Everything else must be identical.
set -euo pipefail

if [[ "${1:-}" == "--compare" ]]; then
    [[ $# -eq 3 ]] || { echo "usage: $0 --compare BEFORE AFTER" >&2; exit 2; }
    exec python3 - "$2" "$3" <<'PY'
import json, os, re, sys
KEYS = re.compile(r'("(?:[a-z_]*seconds|elapsed_s|digest)"\s*:\s*)("[^"]*"|[-0-9.eE+]+|null)')
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
    if name.endswith(".csv") and text.startswith("round,steps,"):
        # Closed-loop training's rounds log: its last two columns are wall times.
        lines = [l.split(",") for l in text.splitlines()]
        return "\n".join(",".join(l[:-2] + ["<time>", "<time>"]) for l in lines)
    # A time right-aligned in a column: its padding goes with it.
    return re.sub(r" *[0-9.]+(e-?[0-9]+)? ?s\b", " <time> s", text)
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
# The human (non --json) forms of the same commands, and the commands whose output is
# only text or files: check, export-vnnlib, closed-loop training, and refused inputs.
run check check "$SPEC"
run verify_human verify "$SPEC" --network "f=$NET"
for p in p1 p2 p3 p4; do
    run "critical_human_$p" critical "$SPEC" --network "f=$NET" --property "$p" --param ystar
done
run robustness_human robustness --network "$NET" --data "$OUT/robustness_data.csv" \
    --eps 1e-4,1e-3 --lipschitz 1e-5,1e-3,1e-2
run robustness_merge_human merge robustness "$OUT/robustness_shard0.json" \
    "$OUT/robustness_shard1.json"
run export_vnnlib export-vnnlib "$SPEC" --network "f=$NET" --out "$OUT/vnnlib"
run verify_vnnlib_human verify-vnnlib --network "$ACAS/ACASXU_run2a_1_2_batch_2000.onnx" \
    --property "$ACAS/prop_2.vnnlib"
run verify_vnnlib_unsat verify-vnnlib --network "$ACAS/ACASXU_run2a_1_1_batch_2000.onnx" \
    --property "$ACAS/prop_1.vnnlib" --json
run vnncomp_human vnncomp "$OUT/instances.csv" --root "$ACAS" --out "$OUT/vnncomp_human.csv"
run vnncomp_merge_human merge vnncomp "$OUT/vnncomp_shard0.json" "$OUT/vnncomp_shard1.json" \
    --out "$OUT/vnncomp_merged_human.csv"
run reach_human reach --network "$DENORM" --threads 1 --horizon 5 --out "$OUT/reach_human"
run reach_system_human reach --system examples/archcomp/acc.sys \
    --network crates/samara-reach/tests/data/archcomp/controller_acc_5_20.onnx \
    --threads 1 --out "$OUT/reach_system_human"
run simulate_system_human simulate --system examples/archcomp/acc.sys \
    --controller crates/samara-reach/tests/data/archcomp/controller_acc_5_20.onnx \
    --out "$OUT/simulate_system_human"
run simulate_net simulate --controller "$DENORM" --y0 2 --horizon 4 --no-plot \
    --out "$OUT/simulate_net" --json
run train_dl2 train --data "$OUT/train_data.csv" --epochs 3 --seed 1 --method dl2 \
    --out "$OUT/train_dl2.onnx" --json
run train_closed_loop train --data "$OUT/train_data.csv" --method closed-loop --epochs 20 \
    --seed 1 --min-r2 0 --rounds 1 --steps-per-round 2 --round-leaves 2 --max-leaves 2 \
    --out "$OUT/train_cl.onnx" --json
# Refused inputs: the message and exit code 2.
run err_simulate_constant simulate --controller constant:0.5 --out "$OUT/e1"
run err_simulate_pid simulate --model reduced --out "$OUT/e2"
run err_simulate_net simulate --controller "$ACAS/ACASXU_run2a_1_1_batch_2000.onnx" --out "$OUT/e3"
run err_simulate_integrator simulate --integrator euler --out "$OUT/e4"
run err_simulate_multiple simulate --horizon 1.2 --period 0.5 --out "$OUT/e5"
run err_train_method train --data "$OUT/train_data.csv" --method nope --out "$OUT/e6.onnx"
run err_train_attack train --data "$OUT/train_data.csv" --method adversarial --attack x \
    --out "$OUT/e7.onnx"
run err_train_arch train --data "$OUT/train_data.csv" --method dl2 --arch 5,4,1 --out "$OUT/e8.onnx"
run err_train_log train --data "$OUT/train_data.csv" --out "$OUT/e9.onnx" --log "$OUT/e9.onnx"
run err_train_margin train --data "$OUT/train_data.csv" --method closed-loop --margin 3 \
    --out "$OUT/e10.onnx"
run err_reach_network reach --network "$OUT/missing.onnx" --out "$OUT/e11"
run err_export_nonempty export-vnnlib "$SPEC" --network "f=$NET" --out "$OUT/vnnlib"
echo "wrote $OUT" >&2
