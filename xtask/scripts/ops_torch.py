#!/usr/bin/env python3
"""PyTorch twin of `cargo xtask bench --ops`: the same ops at the same shapes, forward and
forward + backward (median of --runs after one warm-up), on the CPU with --threads threads.

Usage: ops_torch.py OPS_JSON [--threads 2] [--runs 5]
OPS_JSON is the list of op specs that `cargo xtask bench --ops` writes (name, kind, input, cout,
stride, dilation). Prints one JSON line {"torch": version, "ops": {name: {forward_ms,
forward_backward_ms}}}. Needs: pip install torch.
"""
import argparse
import json
import time

import torch
import torch.nn.functional as F


def median_ms(f, runs):
    f()
    t = []
    for _ in range(max(runs, 1)):
        t0 = time.perf_counter()
        f()
        t.append((time.perf_counter() - t0) * 1e3)
    t.sort()
    return t[len(t) // 2]


def make(op):
    kind, shape, cout = op["kind"], op["input"], op["cout"]
    s, d = op["stride"], op["dilation"]
    x = (torch.rand(*shape) * 2 - 1).requires_grad_()
    if kind in ("conv3d", "conv3d_as_2d"):
        w = (torch.rand(cout, shape[1], 3, 3, 3) * 2 - 1).requires_grad_()
        return lambda: F.conv3d(x, w, None, (1, s, s), (1, d, d), (1, d, d)).mean(), [x, w]
    if kind == "convT3d":
        w = (torch.rand(shape[1], cout, 1, 2, 2) * 2 - 1).requires_grad_()
        return lambda: F.conv_transpose3d(x, w, None, (1, s, s)).mean(), [x, w]
    if kind == "layernorm5":
        norm = torch.nn.LayerNorm(shape[1])
        return lambda: norm(x.permute(0, 2, 3, 4, 1)).permute(0, 4, 1, 2, 3).mean(), [x]
    if kind == "conv2d":
        w = (torch.rand(cout, shape[1], 3, 3) * 2 - 1).requires_grad_()
        return lambda: F.conv2d(x, w, None, 1, 1).mean(), [x, w]
    if kind == "grid_sample":
        b, c, h, w_ = shape
        grid = torch.rand(b, h, w_, 2) * 2 - 1
        return lambda: F.grid_sample(x, grid, mode="bilinear", padding_mode="zeros",
                                     align_corners=False).mean(), [x]
    raise SystemExit(f"unknown op kind {kind}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("ops")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--runs", type=int, default=5)
    a = ap.parse_args()
    torch.set_num_threads(a.threads)
    torch.manual_seed(0)
    out = {}
    for op in json.load(open(a.ops)):
        f, params = make(op)

        def fwd():
            with torch.no_grad():
                f().item()

        def both():
            for p in params:
                p.grad = None
            f().backward()

        out[op["name"]] = {"forward_ms": median_ms(fwd, a.runs),
                           "forward_backward_ms": median_ms(both, a.runs)}
    print(json.dumps({"torch": torch.__version__, "threads": torch.get_num_threads(), "ops": out}))


if __name__ == "__main__":
    main()
