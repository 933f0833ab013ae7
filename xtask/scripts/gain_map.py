#!/usr/bin/env python3
"""Where in the image one method beats another: a map of the squared-error reduction.

Reads the PNGs `cargo xtask eval --samples N` writes (`OUT/samples/NNN/<method>.png` beside
`ground_truth.png`) for every triplet of the evaluation, and writes a picture of the mean over
triplets of (error of B)² − (error of A)² per pixel, colour channels averaged, in the frame's
own coordinates: blue where A is better, red where B is, white where they agree (the scale is
symmetric, its end the 99th percentile of |difference|). It also prints the PSNR difference
A − B on the whole image, on its central 80 % (the PyTorch prototype's crop) and on the outer
band, and which share of the whole-image squared-error reduction lies in that band, and in
bands by distance from the frame's edge:

    python3 xtask/scripts/gain_map.py OUT --a learned_n5_d16 --b sweep_n5_d16 --png map.png

Every sample directory must hold both methods' images; the map averages the samples of the
first one's size, the figures use them all.
"""
import argparse
import os

import numpy as np
from PIL import Image


def load(path):
    if not os.path.exists(path):
        raise SystemExit(f"{path}: missing (did the evaluation write this method's samples?)")
    return np.asarray(Image.open(path).convert("RGB"), dtype=np.float64) / 255.0


def psnr(mse):
    return float(-10 * np.log10(mse))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("out", help="evaluation output directory (with samples/)")
    ap.add_argument("--a", required=True, help="method image name, e.g. learned_n5_d16")
    ap.add_argument("--b", required=True, help="the method it is compared with")
    ap.add_argument("--png", required=True, help="where to write the map")
    ap.add_argument("--crop", type=float, default=0.2, help="share of each side's length cut as the border band, both sides together")
    args = ap.parse_args()
    root = os.path.join(args.out, "samples")
    if not os.path.isdir(root):
        raise SystemExit(f"{root}: no samples directory (run the evaluation with --samples)")
    dirs = sorted(d for d in os.listdir(root) if d.isdigit())
    if not dirs:
        raise SystemExit(f"{root}: no sample directories")
    bands = ((0, 1), (1, 3), (3, 8), (8, 16), (16, 40), (40, 1 << 30))
    band_a, band_b, band_n = (np.zeros(len(bands)) for _ in range(3))
    diff, rows = None, []
    for d in dirs:
        p = os.path.join(root, d)
        gt = load(os.path.join(p, "ground_truth.png"))
        ea = ((load(os.path.join(p, f"{args.a}.png")) - gt) ** 2).mean(axis=2)
        eb = ((load(os.path.join(p, f"{args.b}.png")) - gt) ** 2).mean(axis=2)
        # The map averages the samples of the first sample's size (sequences may differ).
        if diff is None:
            diff, mapped = eb - ea, 1
        elif diff.shape == ea.shape:
            diff, mapped = diff + (eb - ea), mapped + 1
        h, w = ea.shape
        yy, xx = np.mgrid[0:h, 0:w]
        edge = np.minimum.reduce([xx, w - 1 - xx, yy, h - 1 - yy])
        for i, (lo, hi) in enumerate(bands):
            m = (edge >= lo) & (edge < hi)
            band_a[i] += ea[m].sum()
            band_b[i] += eb[m].sum()
            band_n[i] += m.sum()
        ch, cw = int(h * args.crop / 2), int(w * args.crop / 2)
        centre = np.zeros(ea.shape, dtype=bool)
        centre[ch:h - ch, cw:w - cw] = True
        rows.append([psnr(ea.mean()) - psnr(eb.mean()),
                     psnr(ea[centre].mean()) - psnr(eb[centre].mean()),
                     psnr(ea[~centre].mean()) - psnr(eb[~centre].mean()),
                     (eb - ea)[~centre].sum(), (eb - ea).sum()])
    diff /= mapped
    r = np.array(rows)
    share = r[:, 3].sum() / r[:, 4].sum() if r[:, 4].sum() != 0 else float("nan")
    print(f"{len(dirs)} triplets, {args.a} − {args.b} (mean of per-triplet PSNR differences): "
          f"whole image {r[:, 0].mean():+.2f} dB, central {100 - 100 * args.crop:.0f} % "
          f"{r[:, 1].mean():+.2f} dB, outer band {r[:, 2].mean():+.2f} dB; the band holds "
          f"{100 * (1 - centre.mean()):.0f} % of the pixels and {100 * share:.0f} % of the "
          f"squared-error reduction")
    total = (band_b - band_a).sum()
    print("by distance from the frame's edge (px): share of pixels, mean squared error of each, "
          "share of the squared-error reduction")
    for i, (lo, hi) in enumerate(bands):
        if band_n[i] == 0:
            continue
        label = f"{lo}-{hi}" if hi < 1 << 30 else f"{lo}+"
        share = 100 * (band_b[i] - band_a[i]) / total if total != 0 else float("nan")
        print(f"  {label:>6}: {100 * band_n[i] / band_n.sum():5.1f} % of pixels, "
              f"{args.a} {band_a[i] / band_n[i]:.5f}, {args.b} {band_b[i] / band_n[i]:.5f}, "
              f"{share:6.1f} %")
    s = np.percentile(np.abs(diff), 99) or 1.0
    t = np.clip(diff / s, -1, 1)[..., None]
    white, blue, red = np.ones(3), np.array([0.13, 0.4, 0.85]), np.array([0.85, 0.2, 0.13])
    img = np.where(t >= 0, white + t * (blue - white), white - t * (red - white))
    tmp = args.png + ".tmp.png"
    Image.fromarray((img * 255).round().astype(np.uint8)).save(tmp)
    os.replace(tmp, args.png)
    print(f"map: {args.png} ({mapped} of {len(dirs)} samples, those of the first one's size; "
          f"blue: {args.a} better, red: {args.b} better; full scale ±{s:.2e} squared error)")


if __name__ == "__main__":
    main()
