#!/usr/bin/env python3
"""The six-state criterion of issue 14, as one resumable run (`samara reach ... --target-ratio
2` now finds its own cells in one command, docs/reach.md "Adaptive splitting"; this script
keeps the hand-chosen grid and its ledgers): cover the reduced glider's
six-state initial set (+-0.01 on v_xp, v_yp, omega, theta; +-0.05 on x; y0 in the
published interval [0.1, 0.3] m / chord) with a grid of Taylor-model reach runs, give
the cells that are lost or too wide a second round as two halves, and compare the hull
of x + y at t = 20 with the flights' spread.

Round 1 runs every cell of the grid (`samara reach ... --grid ... --shard C/N`, one
process per cell, `--jobs` at a time; `docs/reach.md`, "Grids and shards"). A cell whose
result file exists is not run again, so an interrupted run resumes, and the cells can be
flown elsewhere (a job array) and their files copied into `--out`. Round 2 flies each
cell that was lost, or whose x + y leaves the band, again from its own box cut in two
along `--split` (default theta: measured to repair both kinds of failure). Round 3,
once round 2 is complete, flies the cells still lost or outside the band in four
pieces along the same state.

The band: x + y at t = 20 must lie within the flights' midpoint plus or minus their
spread for the hull to be at most twice the spread (the criterion). The flights are the
cells' own falsification flights (`--samples` over all cells: random starts plus each
cell's centre and corners), or `--band LO:HI` for a spread measured on uniform flights
(`docs/reach.md` gives [-3.905, 2.818] for the adversarial network, 10,000 DOP853
flights, and [-5.79, 2.25] for the base one, 9,960).

Standard library only. Writes DIR/cell-C.json (round 1), DIR/cell-C-split/ (round 2),
DIR/cell-C-quarters/ (round 3) and DIR/summary.json (atomically); exit 0 when the criterion is met, 1 when not (or
not every cell is done), 2 on a usage error.

`--ledger FILE` keeps one JSON line per finished cell and round (the run's settings,
the network's SHA-256, the cell's box, its x + y enclosure or `null` when lost, its
flights' range, seconds, and the commit of the build that flew it, `null` with
`--no-build`). Cells found there
under the same settings are not flown again, so a covering run can be spread over
several sittings (or machines) and kept in the repository
(`bench/reach/six_state_ledger.jsonl`) instead of the 100 KB result files.

    python3 bench/reach/six_state_cover.py --network ../shared/reference/adversarial_model_denorm.onnx \\
        [--jobs 2] [--out out/six-state] [--order 4] [--symbolic 40] [--lifted-weight 2]
        [--grid 3,3,3,3,1,8] [--scale 1.0] [--samples 10000] [--band LO:HI]
        [--split theta] [--cells A:B] [--ledger FILE] [--no-build] [--status]

`--status` flies nothing and builds nothing: it prints how many cells of each round are
done, in the band, too wide or lost, the hull of the settled cells, and the
core-seconds spent and left (from the mean cell so far).

With the defaults (648 cells of a third of v_xp, v_yp, omega and theta, all of x, an
eighth of y) a cell takes 25-45 s on one core for the adversarial network (2026-11-26).
The base network's thirds are lost with `--symbolic 40`; its run is `--grid
3,3,3,6,1,8` (sixths of theta, 1,296 cells of about 22 s) with its own ledger,
`bench/reach/six_state_ledger_base.jsonl`, and `--band=-5.79:2.25`.
"""

import argparse
import concurrent.futures
import hashlib
import json
import os
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
STATES = ["v_xp", "v_yp", "omega", "theta", "x", "y"]
CENTRE = [1.0, 0.0, 0.0, 0.0, 0.0, None]
RADIUS = [0.01, 0.01, 0.01, 0.01, 0.05, None]
Y0 = (0.1 / 0.07, 0.3 / 0.07)
# Rounds 2 and 3: the cell's key for the result, the pieces' word, how many pieces
# along --split, and the result folder's suffix.
AGAIN = {2: ("second", "halves", 2, "split"), 3: ("third", "quarters", 4, "quarters")}


def initial_box(scale):
    """The six-state set, every interval scaled about its midpoint by `scale`."""
    box = []
    for c, r in zip(CENTRE, RADIUS):
        if c is None:
            mid, half = 0.5 * (Y0[0] + Y0[1]), 0.5 * (Y0[1] - Y0[0])
            box.append((mid - scale * half, mid + scale * half))
        else:
            box.append((c - scale * r, c + scale * r))
    return box


def box_flags(box):
    """`--init` for the first five states and `--y0` for y."""
    flags = []
    for name, (lo, hi) in zip(STATES[:5], box[:5]):
        flags += ["--init", f"{name}={lo!r}:{hi!r}"]
    flags += ["--y0", f"{box[5][0]!r}:{box[5][1]!r}"]
    return flags


def write_atomic(path, text):
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        f.write(text)
    os.replace(tmp, path)


def run(cmd, log):
    with open(log, "w") as f:
        return subprocess.run(cmd, stdout=f, stderr=subprocess.STDOUT).returncode


def outcome(reach):
    """(enclosure of x + y or None, flights' range or None) of a reach result."""
    measures = reach.get("measures") or []
    if not measures:
        return None, None
    m = measures[0]
    enc = m.get("enclosure") if reach.get("covered") == 1.0 else None
    return enc, m.get("sampled")


def report_status(cells, again, again3, final, n_cells, spread, band, in_band, ledger):
    """`--status`: what is done, the hull so far and the core-seconds left (estimated
    from the mean cell so far and the share of cells that needed halves)."""
    r1 = [v["seconds"] for v in cells.values() if v["seconds"] is not None]
    lost = sum(1 for v in cells.values() if v["enclosure"] is None)
    wide = sum(1 for v in cells.values() if v["enclosure"] is not None
               and not in_band(v["enclosure"]))
    done2 = [c for c in again if (2, c) in ledger]
    r2 = [ledger[(2, c)]["seconds"] for c in done2 if ledger[(2, c)]["seconds"] is not None]
    repaired = sum(1 for c in done2 if in_band(cells[c]["second"]))
    enclosed = [e for c, e in final.items() if e is not None and (
        in_band(cells[c]["enclosure"]) or (2, c) in ledger or (3, c) in ledger)]
    print(f"round 1: {len(cells)} of {n_cells} cells: "
          f"{len(cells) - lost - wide} in the band, {wide} too wide, {lost} lost")
    print(f"round 2: {len(done2)} of {len(again)} cells flown in halves, "
          f"{repaired} of them now in the band")
    if again3:
        done3 = [c for c in again3 if (3, c) in ledger]
        repaired3 = sum(1 for c in done3 if in_band(cells[c]["third"]))
        print(f"round 3: {len(done3)} of {len(again3)} cells flown in quarters, "
              f"{repaired3} of them now in the band")
    print(f"band x + y in [{band[0]:.3f}, {band[1]:.3f}] (flights "
          f"[{spread[0]:.3f}, {spread[1]:.3f}])")
    if enclosed:
        print(f"hull of the {len(enclosed)} cells settled so far (in the band, or "
              f"enclosed in halves or quarters): "
              f"[{min(e[0] for e in enclosed):.3f}, {max(e[1] for e in enclosed):.3f}]")
    r3 = [ledger[(3, c)]["seconds"] for c in again3
          if (3, c) in ledger and ledger[(3, c)]["seconds"] is not None]
    spent = sum(r1) + sum(r2) + sum(r3)
    if r1:
        mean1 = sum(r1) / len(r1)
        mean2 = sum(r2) / len(r2) if r2 else 2 * mean1
        share = len(again) / len(cells)
        mean3 = sum(r3) / len(r3) if r3 else 2 * mean2
        left = mean1 * (n_cells - len(cells)) + mean2 * (
            len(again) - len(done2) + share * (n_cells - len(cells))) + mean3 * (
            len(again3) - len(r3))
        print(f"core-seconds: {spent:.0f} spent, about {left:.0f} left "
              f"(mean cell {mean1:.1f} s, halves {mean2:.1f} s, "
              f"{100 * share:.0f} % of cells need halves)")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--network", required=True)
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--out", default="out/six-state")
    ap.add_argument("--order", type=int, default=4)
    ap.add_argument("--symbolic", type=int, default=40)
    ap.add_argument("--lifted-weight", type=int, default=2)
    ap.add_argument("--grid", default="3,3,3,3,1,8",
                    help="pieces per state v_xp,v_yp,omega,theta,x,y")
    ap.add_argument("--scale", type=float, default=1.0,
                    help="shrink the set about its midpoint (tests)")
    ap.add_argument("--samples", type=int, default=10000)
    ap.add_argument("--band", help="LO:HI, the spread of x + y over uniform flights")
    ap.add_argument("--split", default="theta", choices=STATES)
    ap.add_argument("--cells", help="A:B, run only cells A..B-1 of round 1")
    ap.add_argument("--ledger", help="JSON-lines record of finished cells (resumable)")
    ap.add_argument("--no-build", action="store_true")
    ap.add_argument("--status", action="store_true",
                    help="report what the ledger and result files hold; fly nothing")
    a = ap.parse_args()

    grid = [int(k) for k in a.grid.split(",")]
    if len(grid) != 6 or any(k < 1 for k in grid) or not 0 < a.scale <= 1 or a.jobs < 1:
        print("six_state_cover: --grid takes six counts >= 1, --scale is in (0, 1], "
              "--jobs >= 1", file=sys.stderr)
        return 2
    if not os.path.isfile(a.network):
        print(f"six_state_cover: no network file {a.network}", file=sys.stderr)
        return 2
    band = None
    if a.band:
        lo, hi = (float(v) for v in a.band.split(":"))
        band = (lo, hi)
    n_cells = 1
    for k in grid:
        n_cells *= k
    first, last = 0, n_cells
    if a.cells:
        first, last = (int(v) for v in a.cells.split(":"))
        if not 0 <= first < last <= n_cells:
            print(f"six_state_cover: --cells must lie in 0:{n_cells}", file=sys.stderr)
            return 2
    if a.status:
        a.no_build = True
    if not a.no_build:
        subprocess.run(["cargo", "build", "--release", "-q", "-p", "samara-cli"],
                       cwd=ROOT, check=True)
    samara = os.path.join(ROOT, "target", "release", "samara")
    os.makedirs(a.out, exist_ok=True)
    with open(a.network, "rb") as f:
        digest = hashlib.sha256(f.read()).hexdigest()
    settings = {"network_sha256": digest, "grid": grid, "scale": a.scale,
                "order": a.order, "symbolic": a.symbolic,
                "lifted_weight": a.lifted_weight, "samples": a.samples}
    # The commit of the build only when this run built it: with --no-build the binary
    # may be older than the checkout (then the ledger says null).
    commit = None
    if not a.no_build:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT,
                                capture_output=True, text=True).stdout.strip() or None
    ledger = {}  # (round, cell) -> entry
    if a.ledger and os.path.isfile(a.ledger):
        with open(a.ledger) as f:
            for line in f:
                e = json.loads(line)
                if e.get("settings") == settings and e["round"] in (1, 2, 3):
                    ledger[(e["round"], e["cell"])] = e

    def record(rnd, c, box, enc, flights, seconds):
        e = {"settings": settings, "round": rnd, "cell": c, "box": box,
             "enclosure": enc, "flights": flights, "seconds": seconds,
             "commit": commit}
        ledger[(rnd, c)] = e
        if a.ledger:
            with open(a.ledger, "a") as f:
                f.write(json.dumps(e) + "\n")

    common = ["--network", a.network, "--sets", "taylor", "--order", str(a.order),
              "--network-error", f"symbolic:{a.symbolic}",
              "--lifted-weight", str(a.lifted_weight), "--max-leaves", "1",
              "--threads", "1"]
    grid_flags = []
    for name, k in zip(STATES, grid):
        if k > 1:
            grid_flags += ["--grid", f"{name}={k}"]
    whole = box_flags(initial_box(a.scale))

    def cell_file(c):
        return os.path.join(a.out, f"cell-{c}.json")

    def load_cell(c):
        """Cell `c` of round 1 from the ledger or its result file (then recorded)."""
        if (1, c) in ledger:
            e = ledger[(1, c)]
            return {k: e[k] for k in ("box", "enclosure", "flights", "seconds")}
        try:
            with open(cell_file(c)) as f:
                reach = json.load(f)["result"]["reach"]
        except (OSError, ValueError, KeyError):
            return None
        enc, flights = outcome(reach)
        cell = {"box": reach["leaves"][0]["init"], "enclosure": enc,
                "flights": flights, "seconds": reach["seconds"]}
        record(1, c, cell["box"], enc, flights, reach["seconds"])
        return cell

    def round1(c):
        rc = 0
        if not a.status and (1, c) not in ledger and not os.path.isfile(cell_file(c)):
            cmd = [samara, "reach"] + common + whole + ["--samples", str(a.samples)] + \
                grid_flags + ["--shard", f"{c}/{n_cells}", "--out", cell_file(c)]
            rc = run(cmd, os.path.join(a.out, f"cell-{c}.log"))
        return c, rc, load_cell(c)

    cells = {}
    with concurrent.futures.ThreadPoolExecutor(a.jobs) as pool:
        for c, rc, cell in pool.map(round1, range(first, last)):
            if a.status:
                if cell is not None:
                    cells[c] = cell
            elif cell is None:
                print(f"cell {c}: no result (exit {rc}; see {a.out}/cell-{c}.log)",
                      flush=True)
            else:
                cells[c] = cell
                state = "enclosed" if cell["enclosure"] else "lost"
                print(f"cell {c}: {state}, {cell['seconds']:.1f} s", flush=True)
    # Cells outside --cells, from the ledger or earlier result files.
    for c in range(n_cells):
        if c not in cells:
            cell = load_cell(c)
            if cell is not None:
                cells[c] = cell
    flown = [v["flights"] for v in cells.values() if v["flights"]]
    own = (min(f[0] for f in flown), max(f[1] for f in flown)) if flown else None
    spread = band or own
    if spread is None:
        print("six_state_cover: no cell has finished", file=sys.stderr)
        return 1
    mid, width = 0.5 * (spread[0] + spread[1]), spread[1] - spread[0]

    def in_band(enc):
        return enc is not None and enc[0] >= mid - width and enc[1] <= mid + width

    # Round 2: the cells lost or outside the band, from their own box in two halves.
    again = [c for c, v in cells.items() if not in_band(v["enclosure"])]

    def again_run(rnd, c):
        """Round `rnd` (2 or 3) of cell `c`: its own box cut in 2 (round 2) or 4 (round
        3) pieces along `--split`."""
        if (rnd, c) in ledger:
            return c, ledger[(rnd, c)]["enclosure"]
        _, _, pieces, name = AGAIN[rnd]
        d = os.path.join(a.out, f"cell-{c}-{name}")
        if a.status and not os.path.isfile(os.path.join(d, "reach.json")):
            return c, None
        if not os.path.isfile(os.path.join(d, "reach.json")):
            box = [tuple(b) for b in cells[c]["box"]]
            cmd = [samara, "reach"] + common + box_flags(box) + \
                ["--samples", str(max(8, a.samples // n_cells)),
                 "--grid", f"{a.split}={pieces}", "--out", d]
            run(cmd, d + ".log")
        try:
            with open(os.path.join(d, "reach.json")) as f:
                res = json.load(f)["result"]
        except (OSError, ValueError, KeyError):
            return c, None
        enc, flights = outcome(res)
        record(rnd, c, cells[c]["box"], enc, flights, res.get("seconds"))
        return c, enc

    def fly_again(rnd, todo):
        key, pieces, _, _ = AGAIN[rnd]
        with concurrent.futures.ThreadPoolExecutor(a.jobs) as pool:
            for c, enc in pool.map(lambda c: again_run(rnd, c), todo):
                cells[c][key] = enc
                if not a.status:
                    print(f"cell {c} in {pieces}: {'enclosed' if enc else 'lost'}",
                          flush=True)

    fly_again(2, again)
    # Round 3: the cells still lost or outside the band after round 2, in quarters.
    # Only once round 2 has flown all its cells (so `--status` counts it right).
    again3 = []
    if all((2, c) in ledger for c in again):
        again3 = [c for c in again if not in_band(cells[c]["second"])]
    fly_again(3, again3)

    final = {c: v.get("third", v.get("second", v["enclosure"])) for c, v in cells.items()}
    missing = [c for c in range(n_cells) if final.get(c) is None]
    hull = None
    if not missing:
        hull = (min(e[0] for e in final.values()), max(e[1] for e in final.values()))
    ratio = (hull[1] - hull[0]) / width if hull else None
    met = ratio is not None and ratio <= 2.0
    if a.status:
        report_status(cells, again, again3, final, n_cells, spread, (mid - width, mid + width),
                      in_band, ledger)
        return 0 if met else 1
    summary = {
        "network": a.network, "grid": grid, "scale": a.scale, "cells": n_cells,
        "done": len(cells), "second_round": len(again), "third_round": len(again3),
        "lost_or_missing": missing, "flights": list(spread),
        "flights_source": "--band" if band else "the cells' own flights",
        "hull": list(hull) if hull else None, "ratio": ratio,
        "cell_seconds": sum(v["seconds"] for v in cells.values()),
        "criterion_met": met,
    }
    write_atomic(os.path.join(a.out, "summary.json"), json.dumps(summary, indent=1) + "\n")
    if hull:
        print(f"x + y at t = 20 in [{hull[0]:.4f}, {hull[1]:.4f}] against flights "
              f"[{spread[0]:.4f}, {spread[1]:.4f}]: ratio {ratio:.3f} "
              f"({'criterion met' if met else 'above 2'})")
    else:
        print(f"{len(missing)} of {n_cells} cells not enclosed (or not run); "
              f"see {a.out}/summary.json")
    return 0 if met else 1


if __name__ == "__main__":
    sys.exit(main())
