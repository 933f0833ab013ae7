#!/usr/bin/env python3
"""`cargo xtask render` with no --run (the pretrained model) against `render --sweep` on the
evaluation triplets of one clip, scored against the real target frame:

    cargo xtask triplets --data ../shared/data/real/re10k-3 --per-sequence 8 --save /tmp/index.json
    python3 xtask/scripts/render_vs_sweep.py ../shared/data/real/re10k-3/test /tmp/index.json SEQUENCE [OUT]

For each triplet of SEQUENCE it writes a camera file (reference, source and target rows), renders
the target at 448 x 256 both ways, and prints the PSNR of each over the pixels both renders cover
(not black), the target frame resized to 448 x 256 (bicubic), and the mean difference. Needs
Pillow; uses target/debug/xtask (or $XTASK).
"""
import json
import math
import os
import subprocess
import sys

from PIL import Image


def main():
    if len(sys.argv) not in (4, 5):
        sys.exit(__doc__)
    root, index, seq = sys.argv[1:4]
    out = sys.argv[4] if len(sys.argv) == 5 else "out/render-vs-sweep"
    xtask = os.environ.get("XTASK", "target/debug/xtask")
    lines = open(f"{root}/{seq}.txt").read().splitlines()
    rows = {int(l.split()[0]): l for l in lines[1:] if l.strip()}
    diffs = []
    for k, t in enumerate(json.load(open(index))["triplets"]):
        if t["sequence"] != seq:
            continue
        ref, src, tgt = t["timestamps"]
        order = sorted(t["timestamps"])
        d = f"{out}/triplet{k:03d}"
        os.makedirs(d, exist_ok=True)
        with open(f"{d}/cams.txt", "w") as f:
            f.write("\n".join([lines[0]] + [rows[x] for x in order]) + "\n")
        row = {x: order.index(x) + 1 for x in order}
        base = [xtask, "render", "--ref", f"{root}/{seq}/{ref}.jpg", "--src", f"{root}/{seq}/{src}.jpg",
                "--cameras", f"{d}/cams.txt", "--ref-row", str(row[ref]), "--src-row", str(row[src]),
                "--size", "448x256", "--orbit-frames", "0", "--overwrite"]
        subprocess.run(base + ["--out", f"{d}/pretrained"], check=True, capture_output=True)
        subprocess.run(base + ["--sweep", "--planes", "16", "--out", f"{d}/sweep"], check=True,
                       capture_output=True)
        gt = Image.open(f"{root}/{seq}/{tgt}.jpg").convert("RGB").resize((448, 256), Image.BICUBIC).tobytes()
        view = f"view_row{row[tgt]:03d}.png"
        a = Image.open(f"{d}/pretrained/{view}").convert("RGB").tobytes()
        b = Image.open(f"{d}/sweep/{view}").convert("RGB").tobytes()
        both = [p for p in range(0, len(gt), 3) if sum(a[p:p + 3]) > 0 and sum(b[p:p + 3]) > 0]

        def psnr(x):
            se = sum(((x[p + c] - gt[p + c]) / 255) ** 2 for p in both for c in range(3))
            return -10 * math.log10(se / (3 * len(both)))

        pa, pb = psnr(a), psnr(b)
        diffs.append(pa - pb)
        print(f"triplet {k} ({t['kind']}, target {tgt}): pretrained {pa:.2f} dB, sweep {pb:.2f} dB, "
              f"difference {pa - pb:+.2f}", flush=True)
    if not diffs:
        sys.exit(f"no triplet of {seq} in {index}")
    print(f"mean difference {sum(diffs) / len(diffs):+.2f} dB over {len(diffs)} triplets "
          f"({sum(x > 0 for x in diffs)} won by the pretrained model)")


if __name__ == "__main__":
    main()
