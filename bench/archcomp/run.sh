#!/usr/bin/env bash
# Run `samara reach` on the ARCH-COMP AINNCS benchmarks and print a markdown table:
# benchmark | samara verdict | samara seconds | expected verdict | best published tool (time) | ratio.
#
# Usage: bench/archcomp/run.sh BENCHMARKS_DIR [ARCH2024_BENCHMARKS_DIR]
#   BENCHMARKS_DIR          the extracted `benchmarks/` folder of verivital/ARCH-COMP2023
#                           (or the repository root that holds it)
#   ARCH2024_BENCHMARKS_DIR optional: `benchmarks/` of verivital/ARCH-COMP2024, for the
#                           networks that exist only there (NAV, CartPole)
# Environment:
#   SAMARA   samara binary (default: `samara` on PATH, else target/release/samara)
#   TIMEOUT  seconds per benchmark (default 1800)
#   OUT      output folder (default out/archcomp); one sub-folder per benchmark
#   ORDER    passed as --order K when set;  MAX_LEAVES  passed as --max-leaves N when set
#            (either one replaces the per-benchmark options of the table below)
#   ONLY     run only the benchmarks whose name contains this string
#   EXTRA    more `samara reach` options for every run, after the others (e.g.
#            EXTRA='--lifted-weight 2' for mixed-degree Taylor models)
# Exit code: 0 when every run ended (whatever the verdicts), 2 on a usage error.
set -u

here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
sysdir="$root/examples/archcomp"
published="$here/published.csv"

if [ $# -lt 1 ] || [ ! -d "$1" ]; then
    echo "usage: $0 BENCHMARKS_DIR [ARCH2024_BENCHMARKS_DIR]  (the benchmarks/ folder of verivital/ARCH-COMP2023)" >&2
    exit 2
fi
b23=$1
[ -d "$b23/benchmarks" ] && b23="$b23/benchmarks"
b24=${2:-}
[ -n "$b24" ] && [ -d "$b24/benchmarks" ] && b24="$b24/benchmarks"

samara=${SAMARA:-}
if [ -z "$samara" ]; then
    if command -v samara >/dev/null 2>&1; then samara=samara; else samara="$root/target/release/samara"; fi
fi
timeout_s=${TIMEOUT:-1800}
out=${OUT:-out/archcomp}
mkdir -p "$out"

# name | system file | network paths, ';'-separated alternatives, relative to the 2023 folder,
#        then to the 2024 folder (`txt:PATH:HIDDEN:OUTPUT` = a POLAR text network, converted
#        to ONNX by polar_txt_to_onnx.py) | expected verdict | published.csv benchmark | instance
#        | samara reach options of this benchmark (optional; not used when ORDER or MAX_LEAVES is set),
#        as the competition's tools tune per benchmark (JuliaReach's DP: 72 boxes, TMJets order 5)
benchmarks='acc|acc.sys|ACC/controller_5_20.onnx|verified|ACC|safe-distance (ReLU)
tora|tora.sys|Benchmark9-Tora/controllerTora.onnx|verified|TORA|remain (ReLU)
tora_het_relu_tanh|tora_heterogeneous.sys|Tora_Heterogeneous/nn_tora_relu_tanh.onnx;txt:Tora_Heterogeneous/nn_tora_relu_tanh.txt:relu:tanh|verified|TORA Heterogeneous|reach-tanh (ReLU/tanh)
tora_het_sigmoid|tora_heterogeneous_sigmoid.sys|Tora_Heterogeneous/nn_tora_sigmoid.onnx;txt:Tora_Heterogeneous/nn_tora_sigmoid.txt:sigmoid:sigmoid|verified|TORA Heterogeneous|reach-sigmoid (u = 22 (N - 0.5))
tora_het_sigmoid_11N|tora_heterogeneous.sys|Tora_Heterogeneous/nn_tora_sigmoid.onnx;txt:Tora_Heterogeneous/nn_tora_sigmoid.txt:sigmoid:sigmoid|verified|TORA Heterogeneous|reach-sigmoid
unicycle|unicycle.sys|Benchmark10-Unicycle/controllerB.onnx|verified|Unicycle|reach
single_pendulum|single_pendulum.sys|Single_Pendulum/controller_single_pendulum.onnx|verified|Single Pendulum|reach
double_pendulum_less|double_pendulum.sys|Double_Pendulum/controller_double_pendulum_less_robust.onnx|verified|Double Pendulum|less-robust|--network-error symbolic:10 --order 3 --max-leaves 128
double_pendulum_more|double_pendulum_more_robust.sys|Double_Pendulum/controller_double_pendulum_more_robust.onnx|falsified|Double Pendulum|more-robust
airplane|airplane.sys|Airplane/controller_airplane.onnx|falsified|Airplane|continuous (t in [0,2])
attitude_control|attitude_control.sys|Aircraft/Attitude Control/attitude_control_3_64_torch.onnx;Attitude-Control/attitude_control_3_64_torch.onnx|verified|Attitude Control|avoid
quadrotor|quadrotor.sys|Aircraft/QUAD/quad_controller_3_64_torch.onnx;QUAD/quad_controller_3_64_torch.onnx|verified|QUAD|reach
quadrotor_competition|quadrotor_competition.sys|Aircraft/QUAD/quad_controller_3_64_torch.onnx;QUAD/quad_controller_3_64_torch.onnx|verified|QUAD|reach (dynamics.m, full initial set)|--order 2
spacecraft_docking|spacecraft_docking.sys|Docking/model.onnx|verified|Docking|constraint
nav_standard|nav.sys|NAV/networks/nn-nav-point.onnx|unknown|NAV|standard
nav_robust|nav.sys|NAV/networks/nn-nav-set.onnx|verified|NAV|robust
cartpole|cartpole.sys|CartPole/model.onnx|unknown|Balancing (CartPole)|reach
vcas_19.5|vcas_competition.sys|VCAS/nnet_networks|verified|VCAS|h0'"'"' = -19.5 (central acceleration)|--init hdot0=-19.5 --choice middle
vcas_22.5|vcas_competition.sys|VCAS/nnet_networks|verified|VCAS|h0'"'"' = -22.5 (central acceleration)|--init hdot0=-22.5 --choice middle
vcas_25.5|vcas_competition.sys|VCAS/nnet_networks|falsified|VCAS|h0'"'"' = -25.5 (central acceleration)|--init hdot0=-25.5 --choice middle
vcas_28.5|vcas_competition.sys|VCAS/nnet_networks|falsified|VCAS|h0'"'"' = -28.5 (central acceleration)|--init hdot0=-28.5 --choice middle'

find_net() {  # $1: ';'-separated relative paths; prints the first that exists
    local IFS=';' rel base txt act_h act_o onnx
    for rel in $1; do
        for base in "$b23" ${b24:+"$b24"}; do
            case "$rel" in
            txt:*)
                IFS=: read -r _ txt act_h act_o <<<"$rel"
                [ -f "$base/$txt" ] || continue
                mkdir -p "$out/nets"
                onnx="$out/nets/$(basename "$txt" .txt).onnx"
                python3 "$here/polar_txt_to_onnx.py" "$base/$txt" "$onnx" \
                    --hidden "$act_h" --output "$act_o" >/dev/null || continue
                printf '%s\n' "$onnx"; return 0 ;;
            *)
                # a file, or a folder of networks (VCAS: one per mode value)
                if [ -e "$base/$rel" ]; then printf '%s\n' "$base/$rel"; return 0; fi ;;
            esac
        done
    done
    return 1
}

# Fields of a reach JSON summary: verdict and seconds ('' when missing).
json_field() {  # $1: file, $2: verdict|seconds
    python3 - "$1" "$2" <<'PY'
import json, sys
try:
    d = json.load(open(sys.argv[1]))
except Exception:
    print(""); sys.exit(0)
if sys.argv[2] == "verdict":
    v = d.get("verdict")
    v = v.get("verdict") if isinstance(v, dict) else v
    print({"proved": "verified", "violated": "falsified"}.get(v, v or ""))
else:
    s = d.get("seconds")
    print("" if s is None else "%.3g" % float(s))
PY
}

# Best published time for a benchmark/instance among the rows of published.csv whose
# tool_verdict is the expected one (any year: the instance label carries the specification,
# rows for other specifications have other labels). tool_seconds is a number, optionally
# prefixed by "~" (approximate, e.g. a developer comment) or "<" (upper bound, e.g. a log
# with whole-second resolution). Prints "tool year|prefix|seconds", or "||" when none.
best_published() {  # $1: benchmark, $2: instance, $3: expected verdict
    python3 - "$published" "$1" "$2" "$3" <<'PY'
import csv, re, sys
path, bench, inst, exp = sys.argv[1:5]
best = None
try:
    rows = list(csv.DictReader(open(path, newline="")))
except OSError:
    rows = []
for r in rows:
    if r["benchmark"] != bench or r["instance"] != inst:
        continue
    m = re.fullmatch(r"\s*([~<]?)\s*([0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?)\s*", r["tool_seconds"] or "")
    if not m or (exp in ("verified", "falsified") and r["tool_verdict"] != exp):
        continue
    prefix, s = m.group(1), float(m.group(2))
    # smallest time first; at equal times an exact figure before "<" and "~"
    key = (s, {"": 0, "<": 1, "~": 2}[prefix])
    if best is None or key < best[0]:
        best = (key, "%s %s" % (r["tool"], r["year"]), prefix)
print("%s|%s|%g" % (best[1], best[2], best[0][0]) if best else "||")
PY
}

# VerticalCAS as the competition's tools run it: hdot0 normalised by the 5000 of
# Specifications.txt instead of the networks' own header range 200 (vcas.sys, `hdot_norm`).
sed 's/^param hdot_norm = 200$/param hdot_norm = 5000/' "$sysdir/vcas.sys" >"$out/vcas_competition.sys"

echo "| benchmark | samara verdict | samara s | expected | best published (s) | ratio |"
echo "|---|---|---|---|---|---|"
notes=""
while IFS='|' read -r name sys nets expected pbench pinst opts; do
    [ -n "${ONLY:-}" ] && case "$name" in *"$ONLY"*) ;; *) continue ;; esac
    bp=$(best_published "$pbench" "$pinst" "$expected")
    IFS='|' read -r btool bpre bsec <<<"$bp"
    best="n/a"; [ -n "$btool" ] && best="$btool ($bpre$bsec)"
    if ! net=$(find_net "$nets"); then
        echo "| $name | no network | | $expected | $best | |"
        notes="$notes\n- $name: no loadable network found ($nets); see bench/archcomp/README.md"
        continue
    fi
    dir="$out/$name"
    rm -rf "$dir"
    extra=()
    # shellcheck disable=SC2206  # the options column is a word list
    [ -n "${opts:-}" ] && [ -z "${ORDER:-}${MAX_LEAVES:-}" ] && extra+=($opts)
    [ -n "${ORDER:-}" ] && extra+=(--order "$ORDER")
    [ -n "${MAX_LEAVES:-}" ] && extra+=(--max-leaves "$MAX_LEAVES")
    # shellcheck disable=SC2206  # EXTRA is a word list
    [ -n "${EXTRA:-}" ] && extra+=($EXTRA)
    start=$(date +%s.%N)
    sysfile="$sysdir/$sys"
    [ -f "$sysfile" ] || sysfile="$out/$sys"
    timeout "$timeout_s" "$samara" reach --system "$sysfile" --network "$net" \
        --out "$dir" --json "${extra[@]}" </dev/null >"$out/$name.json" 2>"$out/$name.err"
    rc=$?
    wall=$(python3 -c "import sys; print('%.3g' % (float(sys.argv[2]) - float(sys.argv[1])))" "$start" "$(date +%s.%N)")
    verdict=$(json_field "$out/$name.json" verdict)
    secs=$(json_field "$out/$name.json" seconds)
    if [ "$rc" -eq 124 ]; then
        verdict="timeout"; secs=">$timeout_s"
    elif [ "$rc" -ge 2 ] || [ -z "$verdict" ]; then
        verdict="error (exit $rc)"; secs=""
        notes="$notes\n- $name: $(head -n 1 "$out/$name.err")"
    fi
    [ -z "$secs" ] && [ "$rc" -lt 2 ] && secs=$wall
    ratio=""
    # only where samara reached the expected verdict (a ratio for `unknown` would mislead)
    if [ -n "$bsec" ] && [ -n "$secs" ] && [ "${secs#>}" = "$secs" ] && [ "$verdict" = "$expected" ]; then
        # samara / published; a published upper bound ("<1") makes the ratio a lower bound
        ratio=$(python3 -c "import sys; print('%.2g' % (float(sys.argv[1]) / float(sys.argv[2])))" "$secs" "$bsec")
        case "$bpre" in "<") ratio=">$ratio" ;; "~") ratio="~$ratio" ;; esac
    fi
    echo "| $name | $verdict | $secs | $expected | $best | $ratio |"
done <<EOF
$benchmarks
EOF
if [ -n "$notes" ]; then
    printf '\nNotes:%b\n' "$notes"
fi
exit 0
