#!/usr/bin/env python3
"""samara on one VNN-COMP benchmark folder, beside every tool of that year.

Runs `samara vnncomp` on the benchmark's instances CSV (all of them, or the first
--limit, or every --every-th), with the competition's timeouts scaled by
--timeout-scale, then writes a markdown table: per instance samara's verdict and time
beside each tool's published verdict (results_csv of stanleybak/vnncomp2021_results),
the disagreements with a decided tool, the decided counts per tool over the same
instances, and every `sat` counterexample re-checked with onnxruntime (the inputs
through the ONNX file in float32, the whole VNN-LIB property evaluated at them).

usage:
  bench/vnncomp/run_benchmark.py BENCH_DIR [--results RESULTS_DIR] [--timeout-scale S]
      [--limit N] [--every K] [--match NET] [--samara BIN] [--md OUT.md]
BENCH_DIR: e.g. benchmarks/verivital of stanleybak/vnncomp2021 (its *_instances.csv);
RESULTS_DIR: results_csv of stanleybak/vnncomp2021_results, or the root of
ChristopherBrix/vnncomp2022_results (TOOL/BENCH/results.csv; pass --year 2022), or of
ChristopherBrix/vnncomp2023_results / vnncomp2024_results (TOOL/YEAR_BENCH/results.csv;
pass --year 2023 or 2024). Instances are matched by their path inside the benchmark
folder (safenlp has networks of the same name in two subfolders), else by file name.
Networks stored gzipped (nn4sys) are unzipped next to a copy of the instances CSV in a
temporary folder.
"""
import argparse
import csv
import gzip
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_acasxu import confirm_with_onnxruntime, norm  # noqa: E402

REPO = Path(__file__).resolve().parents[2]


def rel_key(path, bench_name):
    """An instance file's path inside its benchmark folder (`onnx/sub/net.onnx`), from a
    path of the instances CSV or of a results CSV (`vnncomp2024_benchmarks/benchmarks/
    safenlp/./onnx/...`); `None` if the benchmark's folder is not in the path."""
    p = os.path.normpath(path.strip())
    if p.endswith(".gz"):
        p = p[:-3]
    parts = p.split(os.sep)
    if bench_name in parts:
        k = len(parts) - 1 - parts[::-1].index(bench_name)
        return "/".join(parts[k + 1:])
    return None


def ordinal(n):
    """`2nd`, `3rd`, `5th`, `21st`: the table's text for `--every n`."""
    if n % 100 in (11, 12, 13):
        return f"{n}th"
    return str(n) + {1: "st", 2: "nd", 3: "rd"}.get(n % 10, "th")


def read_peers(results_dir, bench_name, year="2021"):
    """Each tool's verdict and time per (network, property), keyed by the files' paths
    inside the benchmark folder and by their names: the 2021 layout (one CSV per tool,
    `results_csv/TOOL.csv`), the 2022 one (`TOOL/BENCH/results.csv`) or the 2023/2024
    one (`TOOL/YEAR_BENCH/results.csv`)."""
    peers = {}
    files = [(f.stem, f) for f in sorted(Path(results_dir).glob("*.csv"))]
    files += [(f.parent.parent.name, f) for f in sorted(Path(results_dir).glob(f"*/{bench_name}/results.csv"))]
    files += [(f.parent.parent.name, f)
              for f in sorted(Path(results_dir).glob(f"*/{year}_{bench_name}/results.csv"))]
    for tool, f in files:
        rows = {}
        with open(f, newline="") as fh:
            for r in csv.reader(fh):
                if len(r) >= 6 and r[0] == bench_name:
                    try:
                        t = float(r[5])
                    except ValueError:
                        t = float("nan")
                    v = (norm(r[4]), t)
                    rows.setdefault((os.path.basename(r[1]), os.path.basename(r[2])), v)
                    ko, kv = rel_key(r[1], bench_name), rel_key(r[2], bench_name)
                    if ko and kv:
                        rows[(ko, kv)] = v
        if rows:
            peers[tool] = rows
    return peers


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("bench")
    ap.add_argument("--results", default=os.environ.get("SAMARA_VNNCOMP_RESULTS"))
    ap.add_argument("--timeout-scale", default="1")
    ap.add_argument("--limit", type=int, default=0)
    ap.add_argument("--every", type=int, default=1)
    ap.add_argument("--match", default=None, help="only instances whose network path contains this")
    ap.add_argument("--samara", default=None)
    ap.add_argument("--md", default=None, help="write the table here (default: stdout)")
    ap.add_argument("--year", default="2021", help="the competition year of --results (for the table's text)")
    ap.add_argument("--save", default=None, help="also write samara's verdicts here (JSON)")
    ap.add_argument("--load", default=None,
                    help="read samara's verdicts from a --save file instead of running samara "
                         "(the same instances beside another year's results)")
    a = ap.parse_args()
    bench = Path(a.bench).resolve()
    name = bench.name
    insts = sorted(bench.glob("*_instances.csv")) or sorted(bench.glob("instances.csv"))
    if not insts:
        sys.exit(f"{bench}: no *_instances.csv or instances.csv")
    rows = [r for r in csv.reader(open(insts[0])) if r]
    if a.match:
        rows = [r for r in rows if a.match in r[0]]
    rows = rows[:: a.every]
    if a.limit:
        rows = rows[: a.limit]
    binary = a.samara
    if binary is None:
        subprocess.run(["cargo", "build", "--release", "-q", "-p", "samara-cli"], cwd=REPO, check=True)
        binary = str(REPO / "target/release/samara")
    tmp = Path(tempfile.mkdtemp(prefix=f"samara_{name}_"))
    sel, absent = [], []
    key_of = {}  # (onnx, vnnlib) as samara reports them -> paths inside the benchmark
    for onnx, vnnlib, tmo in rows:
        src = (bench / onnx).resolve()
        # The key of the row: its network's path without `.gz`, as `rel_key` gives the
        # peers' (nn4sys's CSV names `nets/X.onnx.gz`, the results `nets/X.onnx`).
        okey = os.path.normpath(onnx)
        okey = okey[:-3] if okey.endswith(".gz") else okey
        if not src.exists() and onnx.endswith(".gz") and (bench / okey).exists():
            src = (bench / okey).resolve()  # the snapshot holds it unpacked
        if not src.exists() and not Path(str(src) + ".gz").exists():
            # A network whose blob the fetched snapshot lacks: a row, not run.
            absent.append((okey, os.path.normpath(vnnlib)))
            continue
        if not src.exists():
            dst = tmp / os.path.normpath(onnx).replace(os.sep, "__")
            if not dst.exists():
                with gzip.open(str(src) + ".gz", "rb") as f, open(dst, "wb") as g:
                    shutil.copyfileobj(f, g)
            src = dst
        prop = str((bench / vnnlib).resolve())
        sel.append((str(src), prop, tmo))
        key_of[(str(src), prop)] = (okey, os.path.normpath(vnnlib))
    # One `samara vnncomp` run per network, so that a network samara refuses (an
    # operator or a size it does not take) stays in the table as rows marked `error`,
    # with the refusal quoted below it, instead of stopping the whole benchmark.
    groups = {}
    for row in sel:
        groups.setdefault(row[0], []).append(row)
    ours, refused = {}, []
    t0 = time.time()
    for g, (net, grows) in enumerate(groups.items() if not a.load else []):
        inst_csv = tmp / f"instances_{g}.csv"
        with open(inst_csv, "w", newline="") as f:
            csv.writer(f).writerows(grows)
        out_csv = tmp / f"samara_{g}.csv"
        p = subprocess.run([binary, "vnncomp", str(inst_csv), "--out", str(out_csv),
                            "--timeout-scale", a.timeout_scale, "--json"],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        if p.returncode == 2:
            why = (p.stderr.strip().splitlines() or ["exit 2"])[-1]
            refused.append((os.path.basename(net), why))
            for onnx, vnnlib, _ in grows:
                ours[key_of[(onnx, vnnlib)]] = {"result": "error", "seconds": 0.0}
            continue
        if p.returncode not in (0, 1):
            sys.exit(f"samara vnncomp exited {p.returncode}: {p.stderr}")
        for r, (onnx, vnnlib, _) in zip(json.loads(p.stdout)["instances"], grows):
            assert os.path.basename(r["onnx"]) == os.path.basename(onnx), (r["onnx"], onnx)
            assert os.path.basename(r["vnnlib"]) == os.path.basename(vnnlib), (r["vnnlib"], vnnlib)
            ours[key_of[(onnx, vnnlib)]] = r
    wall = time.time() - t0
    if a.load:
        saved = json.loads(Path(a.load).read_text())
        ours = {tuple(k): r for k, r in saved["ours"]}
        refused, wall = saved["refused"], saved["wall"]
    if a.save:
        Path(a.save).write_text(json.dumps({"ours": list(ours.items()), "refused": refused, "wall": wall}))
    for k in absent:
        ours[k] = {"result": "absent", "seconds": 0.0}
    peers = read_peers(a.results, name, a.year) if a.results else {}

    def peer(pn, k):
        """Tool `pn`'s verdict on our instance `k` (by path, else by file name)."""
        pr = peers[pn]
        return pr.get(k) or pr.get((os.path.basename(k[0]), os.path.basename(k[1])), ("-", float("nan")))
    names = sorted(peers)
    out = []
    w = out.append
    w(f"## {name}: samara beside the VNN-COMP {a.year} tools\n")
    w(f"{len(ours)} instances of `{insts[0].name}`" + (f" (networks matching `{a.match}`)" if a.match else "")
      + (f" (every {ordinal(a.every)})" if a.every > 1 else "") + (f" (first {a.limit})" if a.limit else "")
      + f"; competition timeouts x {a.timeout_scale}; this machine ({os.cpu_count()} cores, shared); "
      f"wall {wall:.0f} s. Tools' verdicts and times: VNN-COMP {a.year} (AWS hardware per tool).\n")
    w("| network | property | samara | s | " + " | ".join(names) + " |")
    w("|---|---|---|---|" + "---|" * len(names))
    dis = []
    for k, r in ours.items():
        cells = []
        for pn in names:
            v, t = peer(pn, k)
            cells.append(f"{v} {t:.0f}" if t == t else v)
            if r["result"] in ("sat", "unsat") and v in ("sat", "unsat") and v != r["result"]:
                dis.append((k, pn, r["result"], v))
        w(f"| {k[0]} | {k[1]} | {r['result']} | {r['seconds']:.1f} | " + " | ".join(cells) + " |")
    dec = sum(1 for r in ours.values() if r["result"] in ("sat", "unsat"))
    w("")
    w(f"Decided on these {len(ours)} instances: **samara {dec}** "
      f"({sum(1 for r in ours.values() if r['result'] == 'unsat')} unsat, "
      f"{sum(1 for r in ours.values() if r['result'] == 'sat')} sat)"
      + "".join(f"; {pn} {sum(1 for k in ours if peer(pn, k)[0] in ('sat', 'unsat'))}" for pn in names)
      + ".\n")
    for net, why in refused:
        w(f"- refused by samara (its rows are `error`): `{net}`: {why}")
    for net in sorted({k[0] for k in absent}):
        w(f"- not in the fetched snapshot (its rows are `absent`, not run): `{net}`")
    if refused or absent:
        w("")
    # The consensus: the verdict most decided tools give (ties: none).
    against = 0
    for k, r in ours.items():
        votes = [peer(pn, k)[0] for pn in names]
        votes = [v for v in votes if v in ("sat", "unsat")]
        if votes and r["result"] in ("sat", "unsat"):
            top = max(set(votes), key=votes.count)
            if votes.count(top) * 2 > len(votes) and top != r["result"]:
                against += 1
                w(f"- AGAINST THE CONSENSUS: {k}: samara {r['result']}, {votes.count(top)}/{len(votes)} tools {top}")
    w(f"Verdicts against the consensus of the tools that decided: {against}\n")
    w(f"Disagreements with some decided tool: {len(dis)}")
    for d in dis:
        w(f"- {d[0]}: samara {d[2]}, {d[1]} {d[3]}")
    sats = [(k, r) for k, r in ours.items() if r["result"] == "sat"]
    ok = 0
    file_of = {v: key for key, v in key_of.items()}
    for k, r in sats:
        net_file, prop_file = file_of[k]
        good, y = confirm_with_onnxruntime(net_file, prop_file, r["counterexample"]["inputs"])
        ok += good
        if not good:
            w(f"- NOT CONFIRMED by onnxruntime: {k}")
    w(f"\n`sat` counterexamples confirmed by onnxruntime (in the network's own input type, float32 or float64; whole property): {ok}/{len(sats)}\n")
    text = "\n".join(out) + "\n"
    if a.md:
        Path(a.md).write_text(text)
    print(text)
    return 1 if against or ok != len(sats) else 0


if __name__ == "__main__":
    sys.exit(main())
