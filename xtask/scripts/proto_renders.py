#!/usr/bin/env python3
"""Render eval triplets with the PyTorch prototype of issue #13, for `cargo xtask eval --renders`.

    python3 xtask/scripts/proto_renders.py PROTO_SRC CKPT DATA_ROOT INDEX OUT --size WxH [--split test]

PROTO_SRC is a folder holding the prototype's torch_refine.py and torch_sweep.py (the peer's
own, or the copy `proto_on_prior.sh` trains from); CKPT its checkpoint (its planes, depth range
and U-Net widths are read from it). INDEX is a triplet index of DATA_ROOT (`cargo xtask
triplets --data DATA_ROOT --save INDEX`, with timestamps). Every triplet is rendered twice, at
exactly WxH (frames resized with Lanczos, as both programs load them, the intrinsics scaled
per axis as `eval` does): with the trained network (OUT/learned/) and with the network's
residual left out, i.e. the prototype's own training-free sweep (OUT/sweep/), each as
SEQUENCE_REF_SRC_TGT.png by the frames' timestamps (8-bit; the rounding moves a 30 dB PSNR by
less than 0.01 dB). OUT/times.json has the prototype's own time per view in PyTorch on this
machine (the network and the render; loading excluded), for the record only.

Then score both beside our methods on the same triplets:

    cargo xtask eval --data DATA_ROOT --index INDEX --renders proto=OUT/learned \\
        --renders proto-sweep=OUT/sweep --compare proto,proto-sweep ...
"""
import json
import os
import sys
import time

import numpy as np
import torch
from PIL import Image


def parse(argv):
    args, opt = [], {"--size": None, "--split": "test"}
    i = 0
    while i < len(argv):
        if argv[i] in opt:
            if i + 1 >= len(argv):
                sys.exit(f"{argv[i]} needs a value")
            opt[argv[i]] = argv[i + 1]
            i += 2
        else:
            args.append(argv[i])
            i += 1
    if len(args) != 5 or opt["--size"] is None:
        sys.exit(__doc__)
    try:
        w, h = (int(x) for x in opt["--size"].lower().split("x"))
    except ValueError:
        sys.exit(f"--size {opt['--size']!r} must look like 448x256")
    if w < 8 or h < 8:
        sys.exit(f"--size {w}x{h} is too small")
    return args, (w, h), opt["--split"]


def camera_rows(path):
    """Timestamp -> the 18 numbers of a RealEstate10K camera line (fx fy cx cy 0 0 P[3x4])."""
    rows = {}
    with open(path) as f:
        lines = f.read().strip().split("\n")
    for n, line in enumerate(lines[1:], start=2):
        parts = line.split()
        if len(parts) != 19:
            sys.exit(f"{path}:{n}: expected 19 fields, found {len(parts)}")
        rows[int(parts[0])] = [float(v) for v in parts[1:]]
    return rows


def load_view(root, split, seq, ts, row, size):
    w, h = size
    base = os.path.join(root, split, seq, str(ts))
    path = base + ".png" if os.path.exists(base + ".png") else base + ".jpg"
    if not os.path.exists(path):
        sys.exit(f"{base}.png (or .jpg): no such frame")
    im = Image.open(path).convert("RGB").resize((w, h), Image.LANCZOS)
    k = torch.tensor([[row[0] * w, 0, row[2] * w], [0, row[1] * h, row[3] * h], [0, 0, 1]],
                     dtype=torch.float64)
    p = torch.tensor(row[6:18], dtype=torch.float64).reshape(3, 4)
    img = torch.from_numpy(np.asarray(im, dtype=np.float32) / 255).permute(2, 0, 1)
    return img, k, p


def save_png(img, path):
    a = (img.clamp(0, 1).permute(1, 2, 0).numpy() * 255 + 0.5).astype(np.uint8)
    tmp = path + ".tmp.png"
    Image.fromarray(a).save(tmp)
    os.replace(tmp, path)


def main():
    (src, ckpt, root, index, out), size, split = parse(sys.argv[1:])
    for f in ("torch_refine.py", "torch_sweep.py"):
        if not os.path.isfile(os.path.join(src, f)):
            sys.exit(f"{src}/{f}: not found (PROTO_SRC must hold the prototype)")
    sys.path.insert(0, os.path.abspath(src))
    import torch_refine as P  # noqa: E402

    ck = torch.load(ckpt, weights_only=False)
    a = ck["args"]
    net = P.UNet3D(7, tuple(a["widths"]))
    try:
        net.load_state_dict(ck["net"])
    except RuntimeError as e:
        sys.exit(f"{ckpt}: does not fit the network of {src}/torch_refine.py: {e}")
    net.eval()
    z = P.planes(a["D"], a["near"], a["far"])
    with open(index) as f:
        trips = json.load(f)["triplets"]
    for sub in ("learned", "sweep"):
        os.makedirs(os.path.join(out, sub), exist_ok=True)
    cams, times = {}, []
    for k, t in enumerate(trips):
        seq = t["sequence"]
        if "timestamps" not in t:
            sys.exit(f"{index}: triplet {k} has no timestamps (save the index again with "
                     "`cargo xtask triplets --save`)")
        if seq not in cams:
            cams[seq] = camera_rows(os.path.join(root, split, seq + ".txt"))
        views = []
        for ts in t["timestamps"]:
            if ts not in cams[seq]:
                sys.exit(f"{root}/{split}/{seq}.txt has no camera at timestamp {ts}")
            views.append(load_view(root, split, seq, ts, cams[seq][ts], size))
        ref, srcv, tgt = views
        name = "{}_{}_{}_{}.png".format(seq.replace("/", "-"), *t["timestamps"])
        t0 = time.perf_counter()
        with torch.no_grad():
            alpha_s, alpha, _ = P.refine(net, ref, srcv, z)
            grid, inside = P.render_grids(ref, tgt[1], tgt[2], z)
            learned, _ = P.composite(ref[0], alpha, grid, inside)
        times.append((time.perf_counter() - t0) * 1e3)
        with torch.no_grad():
            a0 = alpha_s.clone()
            a0[0] = 1.0  # the far plane opaque, as the prototype's own evaluation renders it
            sweep, _ = P.composite(ref[0], a0, grid, inside)
        for img, sub in ((learned, "learned"), (sweep, "sweep")):
            if not torch.isfinite(img).all():
                sys.exit(f"triplet {k} ({name}): the {sub} render is not finite")
            save_png(img, os.path.join(out, sub, name))
        print(f"{k + 1}/{len(trips)} {name} {times[-1]:.0f} ms", flush=True)
    with open(os.path.join(out, "times.json"), "w") as f:
        json.dump({"ckpt": ckpt, "step": ck.get("step"), "size": list(size),
                   "ms_per_view_learned": times,
                   "mean_ms_after_first": float(np.mean(times[1:])) if len(times) > 1 else None},
                  f, indent=1)


if __name__ == "__main__":
    main()
