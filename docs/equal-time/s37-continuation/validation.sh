#!/bin/bash
# validation of a candidate run: $1 run dir, $2 tag
set -ex
R=$1; T=$2
cargo xtask eval --data ../shared/data/real/llff-6 --data ../shared/data/real/strecha-2 --split train \
  --sequences llff-6/room,strecha-2/entry-p10 --per-sequence 8 --run $R \
  --methods learned,sweep --sweep-grid 5x16 --orbit-frames 0 --samples 0 --out out/$T-val-real
cargo xtask eval --data data/synth --split val --per-sequence 2 --run $R \
  --methods learned,sweep --sweep-grid 5x16 --orbit-frames 0 --samples 0 --out out/$T-val-synth
python3 xtask/scripts/paired_runs.py out/$T-val-real/report.json out/s36-val-real/report.json --method learned --baseline sweep
python3 xtask/scripts/paired_runs.py out/$T-val-synth/report.json out/s36-val-synth/report.json --method learned --baseline sweep
