#!/usr/bin/env python3
"""PyTorch twin of one phase-1 training step of a trained run's configuration, for timing on
the CPU beside `cargo xtask bench --train-step --run RUN --peer xtask/scripts/train_step_torch.py`.

It reads the run's config.json (as mhi-net writes it) and rebuilds, with random weights and
data, what mhi-net's `Trainer::step_with` does in phase 1, split as its `StepTimes` are:

  volume    the plane sweep of the source onto every normal's D planes (grid_sample, no graph),
            the reference beside it, and with the sweep prior its logit channel (divided by 5),
            averaged over scale x scale pixel blocks: [N, C, D, H/scale, W/scale]
  stage1    the 3D U-Net (conv3d 3x3x3 -> LayerNorm over channels -> ReLU blocks, transposed
            convolutions up, a 1x1x1 head with 1 or, with the colour head, 2 channels; residual
            heads return logits), shared by the N normals; its output brought to H x W
            bilinearly (corners aligned); alphas = clamp(sigmoid(prior logit + residual) +
            correction, 0, 1); with the colour head every plane's colour = clamp(reference +
            tanh(m) * (warped source - reference), 0, 1)
  render    grid_sample of [colour | alpha] to the target (bilinear, zeros), front-to-back
            compositing per normal (far plane opaque) -> [N, 3, H, W]; the Soft blend too
  loss      with covered_loss the target where the reference does not cover, then the run's
            loss: 0.15 * L1 + 0.85 * (1 - SSIM) / 2 (3x3 box windows), or L1
  backward  backward, each gradient clipped to norm 1 on its own (burn's per-tensor clip),
            Adam (betas 0.9/0.999, eps 1e-5)

Printed: the parameter count, each part's median ms, one JSON line (also --json FILE).
Usage: train_step_torch.py --config RUN/config.json [--threads 2] [--runs 5] [--warmup 2]
Needs: pip install torch.
"""
import argparse
import json
import sys
import time

import torch
import torch.nn as nn
import torch.nn.functional as F

LOGIT_INPUT_SCALE = 5.0


class Block3d(nn.Module):
    """conv3d 3x3x3 (stride and dilation in the image axes only), LayerNorm over channels, ReLU."""

    def __init__(self, cin, cout, stride, dilation):
        super().__init__()
        self.conv = nn.Conv3d(cin, cout, 3, stride=(1, stride, stride),
                              padding=(1, dilation, dilation), dilation=(1, dilation, dilation))
        self.norm = nn.LayerNorm(cout, eps=1e-5)

    def forward(self, x):
        x = self.norm(self.conv(x).permute(0, 2, 3, 4, 1)).permute(0, 4, 1, 2, 3)
        return F.relu(x)


class UNet3d(nn.Module):
    def __init__(self, in_channels, width, levels, dilations, out_channels, residual):
        super().__init__()
        ch = lambda l: width << l  # noqa: E731
        self.stem = Block3d(in_channels, width, 1, 1)
        self.down = nn.ModuleList(Block3d(ch(l), ch(l + 1), 2, 1) for l in range(levels))
        self.mid = nn.ModuleList(Block3d(ch(levels), ch(levels), 1, d) for d in dilations)
        self.up = nn.ModuleList(nn.ConvTranspose3d(ch(l + 1), ch(l), (1, 2, 2), stride=(1, 2, 2))
                                for l in range(levels))
        self.dec = nn.ModuleList(Block3d(2 * ch(l), ch(l), 1, 1) for l in range(levels))
        self.head = nn.Conv3d(width, out_channels, 1)
        self.residual = residual
        if residual:
            nn.init.zeros_(self.head.weight)
            nn.init.zeros_(self.head.bias)

    def forward(self, x):
        x = self.stem(x)
        skips = []
        for down in self.down:
            skips.append(x)
            x = down(x)
        for mid in self.mid:
            x = x + mid(x)
        for up, dec in reversed(list(zip(self.up, self.dec))):
            x = dec(torch.cat([up(x), skips.pop()], 1))
        y = self.head(x)
        return y if self.residual else torch.sigmoid(y)


def photometric(a, b):
    pool = lambda x: F.avg_pool2d(x, 3, 1)  # noqa: E731
    c1, c2 = 0.01 ** 2, 0.03 ** 2
    mu_a, mu_b = pool(a), pool(b)
    sa = pool(a * a) - mu_a * mu_a
    sb = pool(b * b) - mu_b * mu_b
    sab = pool(a * b) - mu_a * mu_b
    num = (2 * mu_a * mu_b + c1) * (2 * sab + c2)
    den = (mu_a * mu_a + mu_b * mu_b + c1) * (sa + sb + c2)
    ssim = ((1 - num / den).clamp(0, 2)).mean() / 2
    return (a - b).abs().mean() * 0.15 + ssim * 0.85


def median(xs):
    xs = sorted(xs)
    return xs[len(xs) // 2]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--config", required=True, help="a run's config.json")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--warmup", type=int, default=2)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", type=str, default=None, help="also write the result JSON here")
    a = ap.parse_args()
    torch.set_num_threads(a.threads)
    torch.manual_seed(a.seed)

    cfg = json.load(open(a.config))
    s1, u = cfg["stage1"], cfg["stage1"]["unet"]
    for key, plain in (("halve_planes", False), ("prototype_layout", False), ("norm_groups", 0)):
        if u.get(key, plain) != plain:
            sys.exit(f"{a.config}: stage1.unet.{key} = {u[key]} is not in this twin")
    if cfg.get("loss_kind", "Photometric") not in ("Photometric", "L1"):
        sys.exit(f"{a.config}: loss {cfg.get('loss_kind')} is not in this twin (Photometric, L1)")
    n, d = s1["normals"], cfg["planes"]
    h, w = cfg["height"], cfg["width"]
    scale = max(1, s1.get("scale", 1))
    hs, ws = h // scale, w // scale
    prior = cfg.get("prior", "None") not in (None, "None")
    colour = u.get("colour_head", False)
    out_channels = 1 + int(colour)
    nets = nn.ModuleList(
        UNet3d(u["in_channels"], u["width"], u["levels"], u["dilations"], out_channels,
               u.get("residual", False))
        for _ in range(1 if s1.get("share_weights", True) else n))
    params = list(nets.parameters())
    betas = (cfg["optimizer"]["beta_1"], cfg["optimizer"]["beta_2"])
    opt = torch.optim.Adam(params, lr=cfg["lr"], betas=betas, eps=cfg["optimizer"]["epsilon"])
    clip = (cfg["optimizer"].get("grad_clipping") or {}).get("Norm")

    layers = n * d
    g = torch.Generator().manual_seed(a.seed)
    reference = torch.rand(1, 3, h, w, generator=g)
    source = torch.rand(1, 3, h, w, generator=g)
    target = torch.rand(1, 3, h, w, generator=g)
    psv_grid = torch.rand(layers, h, w, 2, generator=g) * 2.1 - 1.05
    psv_valid = (psv_grid.abs() <= 1).all(-1).float().unsqueeze(1)
    grid = torch.rand(layers, h, w, 2, generator=g) * 2.1 - 1.05
    valid = (grid.abs() <= 1).all(-1).float().unsqueeze(1)
    far = torch.tensor([1.0 if l % d == 0 else 0.0 for l in range(layers)]).reshape(layers, 1, 1, 1)
    logit = torch.randn(layers, 1, h, w, generator=g) * 3
    correction = torch.zeros(layers, 1, h, w)
    soft = torch.softmax(torch.rand(n, 1, h, w, generator=g) * 4, 0)
    covered = (torch.rand(1, 1, h, w, generator=g) < 0.9).float() if cfg.get("covered_loss") else None

    def step():
        t0 = time.perf_counter()
        with torch.no_grad():
            warped = F.grid_sample(source.expand(layers, 3, h, w), psv_grid, mode="bilinear",
                                   padding_mode="zeros", align_corners=False) * psv_valid
            channels = [reference.expand(layers, 3, h, w), warped]
            if prior:
                channels.append(logit / LOGIT_INPUT_SCALE)
            full = torch.cat(channels, 1)  # [N*D, C, H, W]
            c = full.shape[1]
            small = F.avg_pool2d(full, scale) if scale > 1 else full
            volume = small.reshape(n, d, c, hs, ws).permute(0, 2, 1, 3, 4).contiguous()
        t1 = time.perf_counter()
        out = nets[0](volume) if len(nets) == 1 else torch.cat(
            [net(volume[i:i + 1]) for i, net in enumerate(nets)], 0)
        if (hs, ws) != (h, w):
            out = F.interpolate(out.reshape(n, out_channels * d, hs, ws), size=(h, w),
                                mode="bilinear", align_corners=True)
        out = out.reshape(n, out_channels, d, h, w)
        alpha = out[:, 0].reshape(layers, 1, h, w)
        alpha = (torch.sigmoid(logit + alpha) + correction).clamp(0, 1) if prior else alpha
        if colour:
            m = out[:, 1].reshape(layers, 1, h, w)
            col = (reference + torch.tanh(m) * (warped - reference)).clamp(0, 1)
        else:
            col = reference.expand(layers, 3, h, w)
        t2 = time.perf_counter()
        sampled = F.grid_sample(torch.cat([col, alpha], 1), grid, mode="bilinear",
                                padding_mode="zeros", align_corners=False) * valid
        al = (sampled[:, 3:4] * (1 - far) + far).reshape(n, d, 1, h, w)
        rgb = sampled[:, :3].reshape(n, d, 3, h, w)
        t = torch.ones(n, 1, h, w)
        mni = torch.zeros(n, 3, h, w)
        for j in reversed(range(d)):
            ta = t * al[:, j]
            mni = mni + rgb[:, j] * ta
            t = t - ta
        _ = (mni * soft).sum(0, keepdim=True)
        t3 = time.perf_counter()
        tgt = target.expand(n, 3, h, w)
        scored = mni * covered + tgt * (1 - covered) if covered is not None else mni
        loss = photometric(scored, tgt) if cfg.get("loss_kind") == "Photometric" else (scored - tgt).abs().mean()
        _ = loss.item()
        t4 = time.perf_counter()
        opt.zero_grad(set_to_none=True)
        loss.backward()
        if clip is not None:
            grads = [p.grad for p in params if p.grad is not None]
            norms = torch._foreach_norm(grads)
            torch._foreach_mul_(grads, [torch.clamp(clip / (x + 1.1754944e-38), max=1.0) for x in norms])
        opt.step()
        t5 = time.perf_counter()
        ms = lambda x, y: (y - x) * 1e3  # noqa: E731
        return {"volume_ms": ms(t0, t1), "stage1_ms": ms(t1, t2), "render_ms": ms(t2, t3),
                "loss_ms": ms(t3, t4), "backward_ms": ms(t4, t5)}

    for _ in range(a.warmup):
        step()
    rows = [step() for _ in range(a.runs)]
    parts = {k: median([r[k] for r in rows]) for k in rows[0]}
    parts["step_ms"] = median([sum(r[k] for k in r if k != "volume_ms") for r in rows])
    result = {"impl": "torch", "torch": torch.__version__, "threads": a.threads, "config": a.config,
              "normals": n, "planes": d, "size": [w, h], "scale": scale, "prior": prior,
              "colour_head": colour, "params": sum(p.numel() for p in params), "runs": a.runs,
              **parts}
    for k, v in parts.items():
        print(f"  {k:<12} {v:8.1f} ms")
    print(json.dumps(result))
    if a.json:
        json.dump(result, open(a.json, "w"))


if __name__ == "__main__":
    main()
