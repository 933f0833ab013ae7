#!/usr/bin/env python3
"""Where a gain comes from: A − B in the central 80 % of the frame (the PyTorch prototype's
metric), in the covered border band (covered pixels in the outer tenth of each side), and over
all covered pixels (our protocol), per triplet kind.

    python3 xtask/scripts/band_gain.py OUT INDEX.json A B [A2 B2 ...]

OUT is a `cargo xtask eval --samples N` folder (N at least the number of triplets): the methods'
PNGs (`learned_n5_d16`, `sweep_n5_d16`, a `--renders` name, ...), `ground_truth.png` and
`covered.png` (the ground truth with the uncovered pixels dimmed to a quarter, from which the
covered mask is read back); INDEX the triplet index the evaluation used (for the kinds). Each
cell is the mean over triplets of the per-triplet PSNR difference; the band's share of the
covered pixels is printed per kind.
"""
import json
import os
import sys

import numpy as np
from PIL import Image


def load(path):
    if not os.path.isfile(path):
        sys.exit(f"{path}: not found (run the evaluation with --samples at least the number of "
                 "triplets, and name methods as their sample PNGs are named)")
    return np.asarray(Image.open(path).convert("RGB"), dtype=np.float64) / 255


def psnr(err, mask):
    return float(-10 * np.log10(max(err[mask].mean(), 1e-12))) if mask.any() else None


def main():
    args = sys.argv[1:]
    if len(args) < 4 or len(args) % 2:
        sys.exit(__doc__)
    out, index, pairs = args[0], args[1], list(zip(args[2::2], args[3::2]))
    trips = json.load(open(index))["triplets"]
    rows = {}
    for k, t in enumerate(trips):
        s = os.path.join(out, "samples", f"{k:03d}")
        gt = load(os.path.join(s, "ground_truth.png"))
        # covered.png is the ground truth where covered and a quarter of it elsewhere.
        covered = np.abs(load(os.path.join(s, "covered.png")) - gt).max(2) < 1.5 / 255
        h, w = covered.shape
        centre = np.zeros_like(covered)
        centre[int(h * 0.1):h - int(h * 0.1), int(w * 0.1):w - int(w * 0.1)] = True
        masks = {"central 80%": centre, "covered border band": covered & ~centre,
                 "all covered": covered}
        r = {"band share": (covered & ~centre).sum() / max(covered.sum(), 1)}
        for a, b in pairs:
            ea = ((load(os.path.join(s, f"{a}.png")) - gt) ** 2).mean(2)
            eb = ((load(os.path.join(s, f"{b}.png")) - gt) ** 2).mean(2)
            for name, m in masks.items():
                pa, pb = psnr(ea, m), psnr(eb, m)
                if pa is not None and pb is not None:
                    r[(a, b, name)] = pa - pb
        rows.setdefault(t["kind"], []).append(r)
    for kind, rs in sorted(rows.items()):
        share = np.mean([r["band share"] for r in rs])
        print(f"{kind} ({len(rs)} triplets; the band holds {share:.0%} of the covered pixels)")
        for a, b in pairs:
            cells = []
            for name in ("central 80%", "covered border band", "all covered"):
                v = [r[(a, b, name)] for r in rs if (a, b, name) in r]
                cells.append(f"{name} {np.mean(v):+.2f}" if v else f"{name} –")
            print(f"  {a} - {b}: " + ", ".join(cells))


if __name__ == "__main__":
    main()
