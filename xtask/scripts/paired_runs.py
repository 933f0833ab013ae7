#!/usr/bin/env python3
"""Paired covered-PSNR differences between two eval reports of the same triplets, for runs that
one report cannot hold together (two runs with the same method, N and D share a row):

    python3 xtask/scripts/paired_runs.py A/report.json B/report.json [--method mpi] [--baseline sweep]
        [--metric psnr_covered] [--bin 4-8] [--b-method soft]

Prints, with 95 % percentile bootstrap intervals over triplets (2000 resamples, seed 0):
METHOD − BASELINE within A, the same within B, and METHOD of A − METHOD of B, paired per triplet,
of METRIC (a per-view score of report.json's measurements: psnr_covered, the default,
lpips_covered, ssim_covered, psnr, ...; for LPIPS lower is better), over the triplets of one
rotation bin with --bin (0-2, 2-4, 4-8 or >8; all by default). With --b-method the last line
compares METHOD of A with that method of B (e.g. one model's consistent blend against another's
Soft).
"""
import json
import random
import sys


def by_triplet(path, method, metric="psnr_covered", rotation_bin=None):
    """METHOD's METRIC per triplet; a report holding METHOD at several N x D (a
    `--sweep-grid` with more than one entry) is refused rather than mixed."""
    out, configs = {}, set()
    for m in json.load(open(path))["measurements"]:
        if (m["method"] == method and m.get(metric) is not None
                and rotation_bin in (None, m.get("bin"))):
            configs.add((m.get("normals"), m.get("planes")))
            out[m["triplet"]] = m[metric]
    if len(configs) > 1:
        sys.exit(f"{path}: {method} appears at several N x D {sorted(configs)}; "
                 "compare reports with one configuration of it")
    return out


def ci(d):
    if not d:
        return "no common triplets"
    rng = random.Random(0)
    bs = sorted(sum(rng.choice(d) for _ in d) / len(d) for _ in range(2000))
    return f"{sum(d) / len(d):+.3f} [{bs[50]:+.3f}, {bs[1949]:+.3f}] (n={len(d)})"


def paired(x, y):
    return [x[k] - y[k] for k in x if k in y]


def options(args, defaults):
    """Take each `--name value` of `defaults` out of `args` (a list, changed in place); returns
    the options with the defaults for those not given."""
    opt = dict(defaults)
    for k in opt:
        if k in args:
            i = args.index(k)
            if i + 1 >= len(args):
                sys.exit(f"{k} needs a value")
            opt[k] = args[i + 1]
            del args[i : i + 2]
    return opt


def main():
    args = sys.argv[1:]
    opt = options(args, {"--method": "mpi", "--baseline": "sweep", "--metric": "psnr_covered",
                         "--bin": None, "--b-method": None})
    if len(args) != 2:
        sys.exit(__doc__)
    a, b = args
    m, base, k = opt["--method"], opt["--baseline"], opt["--metric"]
    of = lambda path, method: by_triplet(path, method, k, opt["--bin"])
    print(f"{k}:" if opt["--bin"] is None else f"{k}, rotation bin {opt['--bin']}:")
    print(f"A {m} - {base}: {ci(paired(of(a, m), of(a, base)))}")
    print(f"B {m} - {base}: {ci(paired(of(b, m), of(b, base)))}")
    mb = opt["--b-method"] or m
    print(f"A {m} - B {mb}: {ci(paired(of(a, m), of(b, mb)))}")


if __name__ == "__main__":
    main()
