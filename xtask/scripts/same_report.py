#!/usr/bin/env python3
"""Compare two eval report.json files apart from what differs run to run (times, the date,
the machine): exit 0 when every score, count and label is identical, else print the first
differences and exit 1. Used to check that a refactor leaves `cargo xtask eval` unchanged:

    python3 xtask/scripts/same_report.py before/report.json after/report.json [--tol 1e-6]

With --tol, numbers may differ by that much (absolute) and the largest difference is printed:
for a change that only reorders floating-point arithmetic.
"""
import json
import sys

VOLATILE = ("_ms", "ms_per_view", "date", "machine", "threads", "elapsed")


def strip(v, path=""):
    if isinstance(v, dict):
        return {
            k: strip(x, f"{path}.{k}")
            for k, x in v.items()
            if not any(k.endswith(s) or k == s for s in VOLATILE)
        }
    if isinstance(v, list):
        return [strip(x, f"{path}[{i}]") for i, x in enumerate(v)]
    return v


TOL = 0.0
LARGEST = [0.0, ""]


def diff(a, b, path, out):
    if isinstance(a, (int, float)) and isinstance(b, (int, float)) and not isinstance(a, bool):
        d = abs(a - b)
        if d > LARGEST[0]:
            LARGEST[0], LARGEST[1] = d, path
        if d > TOL:
            out.append(f"{path}: {a!r} != {b!r}")
        return
    if type(a) is not type(b):
        out.append(f"{path}: {a!r} != {b!r}")
    elif isinstance(a, dict):
        for k in sorted(set(a) | set(b)):
            if k not in a or k not in b:
                out.append(f"{path}.{k}: only in {'after' if k in b else 'before'}")
            else:
                diff(a[k], b[k], f"{path}.{k}", out)
    elif isinstance(a, list):
        if len(a) != len(b):
            out.append(f"{path}: {len(a)} items != {len(b)}")
        for i, (x, y) in enumerate(zip(a, b)):
            diff(x, y, f"{path}[{i}]", out)
    elif a != b:
        out.append(f"{path}: {a!r} != {b!r}")


def main():
    global TOL
    args = sys.argv[1:]
    if "--tol" in args:
        i = args.index("--tol")
        TOL = float(args[i + 1])
        del args[i : i + 2]
    if len(args) != 2:
        sys.exit(__doc__)
    a, b = (strip(json.load(open(p))) for p in args)
    out = []
    diff(a, b, "", out)
    if out:
        print(f"{len(out)} differences; the first:")
        print("\n".join(out[:20]))
        sys.exit(1)
    if LARGEST[0] > 0:
        print(f"equal within {TOL:g} apart from times, date and machine (largest difference {LARGEST[0]:.3g} at {LARGEST[1]})")
    else:
        print("identical apart from times, date and machine")


if __name__ == "__main__":
    main()
