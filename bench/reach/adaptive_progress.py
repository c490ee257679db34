#!/usr/bin/env python3
"""How far an adaptive run (`samara reach ... --target-ratio R`) got: from its
reach.json, the share of the initial set's volume in accepted cells, in cells with sets
to the horizon, and the cells' count by depth (the number of halvings in their id).

Usage: adaptive_progress.py OUT/reach.json
Only the standard library; the volumes are products of the cells' widths over the
states whose initial interval has a width (a point state counts 1)."""

import collections
import json
import sys


def main(path: str) -> None:
    r = json.load(open(path))
    leaves = r["result"]["leaves"]
    cells = r["adaptive"]["cells"]
    init = [[min(l["init"][i][0] for l in leaves), max(l["init"][i][1] for l in leaves)]
            for i in range(len(leaves[0]["init"]))]

    def vol(box):
        v = 1.0
        for (a, b), (lo, hi) in zip(box, init):
            if hi > lo:
                v *= (b - a) / (hi - lo)
        return v

    acc = sum(vol(l["init"]) for l, c in zip(leaves, cells) if c["accepted"])
    reached = sum(vol(l["init"]) for l in leaves if l["failure"] is None and l["end_measures"])
    depth = collections.Counter(len(c["id"].split(".")[1]) if "." in c["id"] else 0 for c in cells)
    a = r["adaptive"]
    print(f"cells {len(cells)} ({a['accepted']} accepted), flown {a['flown']} in {a['rounds']} rounds; "
          f"stopped: {a['stopped']}")
    print(f"volume accepted {100 * acc:.2f} %, with sets to the horizon {100 * reached:.2f} %")
    print("cells by depth:", dict(sorted(depth.items())))
    print("accepted by depth:", dict(sorted(collections.Counter(
        len(c["id"].split(".")[1]) if "." in c["id"] else 0 for c in cells if c["accepted"]).items())))


if __name__ == "__main__":
    main(sys.argv[1])
