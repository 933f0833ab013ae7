#!/usr/bin/env python3
"""METHOD − BASELINE averaged over runs of several seeds, paired per triplet: each report holds
one seed's pair (e.g. a learned MHI and the learned MPI of the same recipe and seed), all of the
same triplets; each triplet's score of METHOD and of BASELINE is averaged over the reports
first, so the difference is the recipe's, not one seed's:

    python3 xtask/scripts/seed_average.py SEED0/report.json SEED1/report.json [...] \\
        [--method learned] [--baseline mpi]

Prints the seed-averaged difference of covered PSNR with its 95 % percentile bootstrap interval
over triplets (2000 resamples, seed 0), overall and per rotation bin, and each report's own
difference. Reports of different triplets are refused.
"""
import json
import sys

from paired_runs import ci, options


def scores(path, method):
    """Per triplet: (sequence, target, bin) and METHOD's covered PSNR; METHOD at several N x D
    is refused rather than mixed."""
    out, configs = {}, set()
    for m in json.load(open(path))["measurements"]:
        if m["method"] == method and m.get("psnr_covered") is not None:
            configs.add((m.get("normals"), m.get("planes")))
            out[m["triplet"]] = ((m["sequence"], m["target"], m["bin"]), m["psnr_covered"])
    if len(configs) > 1:
        sys.exit(f"{path}: {method} appears at several N x D {sorted(configs)}")
    if not out:
        sys.exit(f"{path}: no covered PSNR of {method}")
    return out


def main():
    args = sys.argv[1:]
    opt = options(args, {"--method": "learned", "--baseline": "mpi"})
    if len(args) < 2:
        sys.exit(__doc__)
    m, base = opt["--method"], opt["--baseline"]
    a = [scores(p, m) for p in args]
    b = [scores(p, base) for p in args]
    keys = sorted(set.intersection(*(set(x) for x in a + b)))
    for x in a + b:
        for k in keys:
            if x[k][0] != a[0][k][0]:
                sys.exit(f"triplet {k} differs between the reports: {x[k][0]} and {a[0][k][0]}")
    diff = {k: sum(x[k][1] for x in a) / len(a) - sum(x[k][1] for x in b) / len(b) for k in keys}
    print(f"{m} - {base}, averaged over {len(args)} reports: {ci(list(diff.values()))}")
    for bn in ["0-2", "2-4", "4-8", ">8"]:
        d = [diff[k] for k in keys if a[0][k][0][2] == bn]
        if d:
            print(f"  rotation {bn} deg: {ci(d)}")
    for p, x, y in zip(args, a, b):
        print(f"  {p}: {ci([x[k][1] - y[k][1] for k in keys])}")


if __name__ == "__main__":
    main()
