#!/usr/bin/env python3
"""Write nearest-view validation triplets of held-out sequences as a triplet index for `cargo xtask eval --index`.

The PyTorch prototype of issue #13 validates on its held-out sequence with triplets of nearest
views: for `--count` references spread evenly over the sequence's views, the source is the
reference's nearest view by camera centre and the target its second nearest, or (every other
reference) the other way round. On a sparse capture (LLFF, Strecha) these are the small
baselines that RealEstate10K's test triplets (5 video frames apart) show, where clips of
consecutive views span several times more. This writes the same triplets for the named
sequences, in the file order of each camera file, with the kind from where the target lies (an
interpolation when its centre projects strictly inside the reference-source segment, as
`--triplets neighbours` decides) and the rotation bin. Sequences are named as `cargo xtask eval`
names them: `<root folder>/<sequence>` when several `--data` roots are given, so the index goes
with the same `--data` list:

    python3 xtask/scripts/neighbour_triplets.py --data ../shared/data/real/llff-6 \
        --data ../shared/data/real/strecha-2 --split train \
        --sequences llff-6/room,strecha-2/entry-p10 /tmp/nv-val.json

Validation data only: never run it on a test split to choose anything.
"""
import argparse
import json
import math
import os

from proto_triplets import angle_deg, bin_of  # the same rotation and bins as the test index


def pose(row):
    p = [float(v) for v in row[7:19]]
    r = [p[0:3], p[4:7], p[8:11]]
    t = [p[3], p[7], p[11]]
    # camera centre c = -Rᵀ t
    c = [-sum(r[k][i] * t[k] for k in range(3)) for i in range(3)]
    return r, c


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", action="append", required=True, help="dataset root (repeatable)")
    ap.add_argument("--split", default="train")
    ap.add_argument("--sequences", required=True,
                    help="comma-separated sequences; ROOT_FOLDER/SEQ with several --data")
    ap.add_argument("out")
    ap.add_argument("--count", type=int, default=8, help="references per sequence (default 8)")
    a = ap.parse_args()
    if os.path.exists(a.out):
        raise SystemExit(f"{a.out} exists; not overwriting it")
    if a.count < 1:
        raise SystemExit(f"--count {a.count}: must be at least 1")
    triplets = []
    roots = {os.path.basename(os.path.normpath(r)): r for r in a.data}
    if len(roots) != len(a.data):
        raise SystemExit("two --data roots share a folder name")
    for seq in a.sequences.split(","):
        if len(a.data) == 1:
            root, name = a.data[0], seq
        else:
            prefix, _, name = seq.partition("/")
            if prefix not in roots or not name:
                raise SystemExit(f"--sequences: '{seq}' is not ROOT_FOLDER/SEQ of a --data root "
                                 f"({', '.join(sorted(roots))})")
            root = roots[prefix]
        f = os.path.join(root, a.split, name + ".txt")
        if not os.path.exists(f):
            raise SystemExit(f"{f}: no such camera file (sequence '{seq}')")
        with open(f) as fh:
            rows = [line.split() for line in fh.read().strip().split("\n")[1:]]
        for n, r in enumerate(rows, start=2):
            if len(r) != 19:
                raise SystemExit(f"{f}:{n}: expected 19 fields, got {len(r)}")
        if len(rows) < 3:
            raise SystemExit(f"{f}: {len(rows)} views, a triplet needs 3")
        poses = [pose(r) for r in rows]
        for n, (_, c) in enumerate(poses, start=2):
            if not all(math.isfinite(v) for v in c):
                raise SystemExit(f"{f}:{n}: camera centre is not finite")

        def dist2(i, j):
            return sum((poses[i][1][k] - poses[j][1][k]) ** 2 for k in range(3))

        count = min(a.count, len(rows))
        refs = [round(k * (len(rows) - 1) / max(count - 1, 1)) for k in range(count)]
        for k, i in enumerate(refs):
            near = sorted((j for j in range(len(rows)) if j != i), key=lambda j: (dist2(i, j), j))
            src, tgt = (near[0], near[1]) if k % 2 == 0 else (near[1], near[0])
            ci, cs, ct = (poses[x][1] for x in (i, src, tgt))
            base = [cs[m] - ci[m] for m in range(3)]
            bb = sum(v * v for v in base)
            along = sum((ct[m] - ci[m]) * base[m] for m in range(3)) / bb if bb > 0 else float("nan")
            kind = "interpolation" if 0.0 < along < 1.0 else "extrapolation"
            rs = [poses[x][0] for x in (i, src, tgt)]
            deg = max(angle_deg(rs[0], rs[1]), angle_deg(rs[0], rs[2]), angle_deg(rs[1], rs[2]))
            triplets.append({
                "sequence": seq, "reference": i, "source": src, "target": tgt, "kind": kind,
                "max_rotation_deg": deg, "bin": bin_of(deg),
                "timestamps": [int(rows[x][0]) for x in (i, src, tgt)],
            })
    tmp = a.out + ".tmp"
    with open(tmp, "w") as fh:
        json.dump({"seed": 0, "triplets": triplets}, fh, indent=1)
    os.replace(tmp, a.out)
    kinds = {k: sum(t["kind"] == k for t in triplets) for k in ("interpolation", "extrapolation")}
    print(f"{len(triplets)} triplets ({kinds['interpolation']} interpolation, "
          f"{kinds['extrapolation']} extrapolation) -> {a.out}")


if __name__ == "__main__":
    main()
