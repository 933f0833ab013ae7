#!/usr/bin/env python3
"""Write the PyTorch prototype's test triplets as a triplet index for `cargo xtask eval --triplets`.

The prototype of issue #13 (a residual 3D U-Net on the sweep's alpha logits, evaluated with its own
`test` mode) scores, per sequence, `--count` evenly spaced starts i with frame gap g:
interpolation (reference i, source i + 2g, target i + g) and extrapolation (reference i, source
i + g, target i + 2g). This writes the same triplets, in the file order of each sequence's camera
file, so that our models are scored on the triplets the prototype reported (the metric stays
ours: covered PSNR, and the whole image beside it).

    python3 xtask/scripts/proto_triplets.py ../shared/data/real/re10k-3 test /tmp/proto.json
"""
import argparse
import glob
import json
import math
import os


def rotation(row):
    p = [float(v) for v in row[7:19]]
    return [p[0:3], p[4:7], p[8:11]]


def angle_deg(ra, rb):
    # trace(Ra Rbᵀ) = Σ_ij Ra_ij Rb_ij
    tr = sum(ra[i][j] * rb[i][j] for i in range(3) for j in range(3))
    return math.degrees(math.acos(max(-1.0, min(1.0, (tr - 1.0) / 2.0))))


def bin_of(deg):
    return "0-2" if deg <= 2 else "2-4" if deg <= 4 else "4-8" if deg <= 8 else ">8"


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("root")
    ap.add_argument("split")
    ap.add_argument("out")
    ap.add_argument("--gap", type=int, default=5)
    ap.add_argument("--count", type=int, default=8)
    a = ap.parse_args()
    if os.path.exists(a.out):
        raise SystemExit(f"{a.out} exists; not overwriting it")
    files = sorted(glob.glob(os.path.join(a.root, a.split, "*.txt")))
    if not files:
        raise SystemExit(f"no camera files in {os.path.join(a.root, a.split)}")
    triplets = []
    for f in files:
        seq = os.path.basename(f)[:-4]
        with open(f) as fh:
            rows = [line.split() for line in fh.read().strip().split("\n")[1:]]
        for n, r in enumerate(rows, start=2):
            if len(r) != 19:
                raise SystemExit(f"{f}:{n}: expected 19 fields, got {len(r)}")
        g = a.gap
        starts = list(range(len(rows) - 2 * g))
        if not starts:
            raise SystemExit(f"{f}: {len(rows)} frames, too few for gap {g}")
        starts = [starts[round(k * (len(starts) - 1) / max(a.count - 1, 1))] for k in range(a.count)]
        for i in starts:
            for kind, (ref, src, tgt) in (("interpolation", (i, i + 2 * g, i + g)),
                                          ("extrapolation", (i, i + g, i + 2 * g))):
                rs = [rotation(rows[k]) for k in (ref, src, tgt)]
                deg = max(angle_deg(rs[0], rs[1]), angle_deg(rs[0], rs[2]), angle_deg(rs[1], rs[2]))
                triplets.append({
                    "sequence": seq, "reference": ref, "source": src, "target": tgt, "kind": kind,
                    "max_rotation_deg": deg, "bin": bin_of(deg),
                    "timestamps": [int(rows[k][0]) for k in (ref, src, tgt)],
                })
    tmp = a.out + ".tmp"
    with open(tmp, "w") as fh:
        json.dump({"seed": 0, "triplets": triplets}, fh, indent=1)
    os.replace(tmp, a.out)
    print(f"{len(triplets)} triplets ({len(files)} sequences, gap {a.gap}, {a.count} starts each) -> {a.out}")


if __name__ == "__main__":
    main()
