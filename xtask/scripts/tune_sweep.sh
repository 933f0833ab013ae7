#!/usr/bin/env bash
# How the training-free sweep's constants were chosen: a grid of window radius x temperature,
# scored by covered PSNR on the *validation* sequences only (llff-6/room and strecha-2/entry-p10,
# the sequences held out of training; never re10k-3, never herzjesus-p8), N = 5, D = 32,
# 8 triplets per sequence.
# Usage: bash xtask/scripts/tune_sweep.sh [SHARED_DATA_DIR] [OUT_DIR]
#   WINDOWS="2 4 6 8" TEMPERATURES="0.0025 0.005 0.01 0.02 0.04" choose the grid;
#   XTASK=/path/to/xtask runs a built binary instead of `cargo xtask` (so that editing the
#   sources meanwhile cannot change what runs).
# Prints one line per configuration and appends to OUT_DIR/tune_sweep.csv (configurations
# already there are skipped, so the grid can be widened and the script run again).
set -euo pipefail
data=${1:-../shared/data/real}
out=${2:-out/tune-sweep}
windows=${WINDOWS:-"2 4 6 8"}
temperatures=${TEMPERATURES:-"0.0025 0.005 0.01 0.02 0.04"}
mkdir -p "$out"
csv="$out/tune_sweep.csv"
[ -f "$csv" ] || echo "window,temperature,psnr_covered,lo,hi,ssim_covered,triplets" > "$csv"
for r in $windows; do
  for t in $temperatures; do
    if grep -q "^$r,$t," "$csv"; then continue; fi
    d="$out/w${r}_t${t}"
    ${XTASK:-cargo xtask} eval --data "$data/llff-6" --data "$data/strecha-2" --split train \
      --sequences llff-6/room,strecha-2/entry-p10 --per-sequence 8 --methods sweep \
      --sweep-grid 5x32 --sweep-window "$r" --sweep-temperature "$t" --samples 0 \
      --orbit-frames 0 --out "$d" --overwrite > "$d.log" 2>&1 || { cat "$d.log"; exit 1; }
    python3 - "$d/report.json" "$r" "$t" >> "$csv" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
row = next(x for x in r["rows"] if x["bin"] == "all" and x["kind"] == "all")
lo, hi = row["psnr_covered_ci"]
print(f'{sys.argv[2]},{sys.argv[3]},{row["psnr_covered"]:.3f},{lo:.3f},{hi:.3f},{row["ssim_covered"]:.4f},{row["count"]}')
PY
    tail -1 "$csv"
  done
done
echo "best by covered PSNR:"
tail -n +2 "$csv" | sort -t, -k3 -g -r | head -3
