#!/usr/bin/env python3
"""Score an evaluation's sample images with the PyTorch prototype's metric (issue #13).

The prototype reports PSNR of the whole image (pixels no input sees stay black) over its central
80 % (a tenth of each side cropped), per triplet kind, and the paired difference of two methods
with a bootstrap interval (1,000 resamples, seed 0, percentiles 2.5 / 97.5). This reads the
PNGs `cargo xtask eval --samples N` writes (`OUT/samples/NNN/<method>.png` beside
`ground_truth.png`), with the triplet index the evaluation used for the kinds:

    python3 xtask/scripts/proto_metric.py OUT INDEX.json --a learned_n5_d16 --b sweep_n5_d16

With `--b-out OUT2` the second method's images come from another evaluation of the same index
(e.g. a sweep-only evaluation re-run with other sweep constants); the ground truths of the two
must be identical, which is checked.

Every triplet of the index must have its sample directory (run the evaluation with --samples at
least the number of triplets).
"""
import argparse
import json
import os

import numpy as np
from PIL import Image


def psnr_crop(a, b, crop=0.2):
    h, w = int(a.shape[0] * crop / 2), int(a.shape[1] * crop / 2)
    a, b = a[h:a.shape[0] - h, w:a.shape[1] - w], b[h:b.shape[0] - h, w:b.shape[1] - w]
    return float(-10 * np.log10(((a - b) ** 2).mean()))


def boot(d, n=1000, seed=0):
    g = np.random.default_rng(seed)
    d = np.asarray(d)
    m = [d[g.integers(0, len(d), len(d))].mean() for _ in range(n)]
    return float(d.mean()), float(np.percentile(m, 2.5)), float(np.percentile(m, 97.5))


def load(path):
    if not os.path.exists(path):
        raise SystemExit(f"{path}: missing (did the evaluation run with --samples covering every triplet?)")
    return np.asarray(Image.open(path).convert("RGB"), dtype=np.float64) / 255.0


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("out")
    ap.add_argument("index")
    ap.add_argument("--a", required=True, help="method image name, e.g. learned_n5_d16")
    ap.add_argument("--b", required=True, help="the method it is compared with")
    ap.add_argument("--b-out", help="evaluation directory of --b (default: OUT)")
    args = ap.parse_args()
    triplets = json.load(open(args.index))["triplets"]
    rows = {"interpolation": [], "extrapolation": []}
    for k, t in enumerate(triplets):
        d = os.path.join(args.out, "samples", f"{k:03}")
        gt = load(os.path.join(d, "ground_truth.png"))
        db = d if args.b_out is None else os.path.join(args.b_out, "samples", f"{k:03}")
        if db != d and not np.array_equal(load(os.path.join(db, "ground_truth.png")), gt):
            raise SystemExit(f"{db}: its ground truth differs from {d}'s: not the same index")
        pa = psnr_crop(load(os.path.join(d, f"{args.a}.png")), gt)
        pb = psnr_crop(load(os.path.join(db, f"{args.b}.png")), gt)
        rows[t["kind"]].append((pa, pb))
    both = []
    for kind, r in rows.items():
        if not r:
            continue
        a, b = np.array(r).T
        m, lo, hi = boot(a - b)
        both.append(m)
        print(f"{kind}: n={len(r)} {args.a} {a.mean():.2f} dB, {args.b} {b.mean():.2f} dB, "
              f"difference {m:+.2f} [{lo:+.2f}, {hi:+.2f}]")
    if len(both) == 2:
        print(f"mean of the two kinds: {sum(both) / 2:+.2f} dB")


if __name__ == "__main__":
    main()
