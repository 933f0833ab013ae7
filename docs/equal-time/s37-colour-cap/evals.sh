set -x
cd /work/main
R=out/s37-colour-cap
bash /tmp/val.sh $R s37-cap
python3 xtask/scripts/proto_triplets.py ../shared/data/real/re10k-3 test /tmp/proto.json
cargo xtask eval --data ../shared/data/real/re10k-3 --index /tmp/proto.json --short-side 144 --samples 48 \
  --run $R --methods learned,sweep,nearest --sweep-grid 5x16 --orbit-frames 0 --out out/s37-cap-proto
python3 xtask/scripts/proto_metric.py out/s37-cap-proto /tmp/proto.json --a learned_n5_d16 --b sweep_n5_d16
cargo xtask eval --data ../shared/data/real/re10k-3 --per-sequence 8 --run $R \
  --methods learned,sweep --sweep-grid 5x16 --orbit-frames 0 --samples 0 --out out/s37-cap-re10k
python3 xtask/scripts/paired_runs.py out/s37-cap-re10k/report.json out/s37-ship-re10k/report.json --method learned --baseline sweep
