#!/usr/bin/env python3
"""Whose gain over its own prior is larger: (A − B) − (C − D), paired per triplet, from one eval
report that scored all four on the same triplets:

    python3 xtask/scripts/gain_difference.py REPORT.json A B C D [--metric psnr_covered]

A method is named as in the report, with @NxD where it appears at several N x D (a
`--sweep-grid` with more than one entry), e.g.

    python3 xtask/scripts/gain_difference.py out/eval/report.json \\
        learned sweep@5x16 proto proto-sweep

for "our learned model's gain over our sweep, against the prototype's gain over its own sweep"
(proto and proto-sweep scored with `eval --renders`). Prints each gain and their difference, for
all triplets and per kind (interpolation, extrapolation), as mean [95 % percentile bootstrap
interval over triplets, 2000 resamples, seed 0], and the mean of the two kinds' means (the
figure issue #13 asks of re10k-3: "averaged over interpolation and extrapolation").
"""
import json
import os
import random
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from paired_runs import ci, options  # noqa: E402


def scores(path, spec, metric):
    """Triplet -> (kind, score) of the method `spec` (NAME or NAME@NxD)."""
    name, _, config = spec.partition("@")
    want = None
    if config:
        try:
            want = tuple(int(v) for v in config.lower().split("x"))
        except ValueError:
            sys.exit(f"{spec}: after @ give N x D, e.g. sweep@5x16")
    out, configs = {}, set()
    for m in json.load(open(path))["measurements"]:
        if m["method"] != name or m.get(metric) is None:
            continue
        c = (m.get("normals"), m.get("planes"))
        configs.add(c)
        if want is None or c == want:
            out[m["triplet"]] = (m["kind"], m[metric])
    if not configs:
        sys.exit(f"{path}: no {metric} of {name!r}")
    if want is None and len(configs) > 1:
        sys.exit(f"{path}: {name} appears at several N x D {sorted(configs)}; name one as "
                 f"{name}@{sorted(configs)[0][0]}x{sorted(configs)[0][1]}")
    if want is not None and want not in configs:
        sys.exit(f"{path}: {name} has no N x D {want}; it has {sorted(configs)}")
    return out


def boot_mean_of_kinds(d_by_kind, resamples=2000):
    """Mean of the per-kind means, with an interval resampling each kind's triplets apart."""
    kinds = [v for v in d_by_kind.values() if v]
    rng = random.Random(0)
    bs = sorted(sum(sum(rng.choice(v) for _ in v) / len(v) for v in kinds) / len(kinds)
                for _ in range(resamples))
    m = sum(sum(v) / len(v) for v in kinds) / len(kinds)
    lo, hi = bs[int(0.025 * resamples)], bs[int(0.975 * resamples) - 1]
    return f"{m:+.3f} [{lo:+.3f}, {hi:+.3f}]"


def main():
    args = sys.argv[1:]
    opt = options(args, {"--metric": "psnr_covered"})
    if len(args) != 5:
        sys.exit(__doc__)
    path, *specs = args
    s = [scores(path, x, opt["--metric"]) for x in specs]
    common = sorted(set.intersection(*(set(x) for x in s)))
    if not common:
        sys.exit(f"{path}: the four methods share no triplet")
    a, b, c, d = specs
    rows = {
        f"{a} - {b}": lambda t: s[0][t][1] - s[1][t][1],
        f"{c} - {d}": lambda t: s[2][t][1] - s[3][t][1],
        f"({a} - {b}) - ({c} - {d})":
            lambda t: (s[0][t][1] - s[1][t][1]) - (s[2][t][1] - s[3][t][1]),
    }
    kinds = sorted({s[0][t][0] for t in common})
    print(f"{path}: {opt['--metric']}, {len(common)} triplets")
    for label, f in rows.items():
        by_kind = {k: [f(t) for t in common if s[0][t][0] == k] for k in kinds}
        parts = [f"all {ci([f(t) for t in common])}"]
        parts += [f"{k} {ci(v)}" for k, v in by_kind.items()]
        if len(kinds) > 1:
            parts.append(f"mean of kinds {boot_mean_of_kinds(by_kind)}")
        print(f"{label}:\n  " + "\n  ".join(parts))


if __name__ == "__main__":
    main()
