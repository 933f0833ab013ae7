#!/usr/bin/env bash
# Train and test the PyTorch prototype of issue #13 on another sweep prior.
#
# The prototype (a residual 3D U-Net on the alpha logits of an N = 1, D = 32 sweep; see
# models/mhi-n5d16/MODEL.md, "At equal training time") averages its photo-consistency cost over
# a 7 x 7 box at a short side of 144 px, with softmax temperature 0.02 and cost 0.5 where the
# source does not see a plane. Our sweep uses a (2r + 1)^2 box with r = 16 at a short side of
# 256 (9 at 144: 19 x 19), temperature 0.005 and cost 0.25 (mhi_render::SweepConfig). This
# copies the prototype's two files into OUT, changes those three constants (and nothing else),
# trains it for MINUTES and tests it on re10k-3 with its own `test` mode. Its "sweep" column is
# then the prior it was given, so "learned - sweep" is the prototype's gain over that prior.
#
#   bash xtask/scripts/proto_on_prior.sh PEER_DIR DATA_DIR OUT [BOX TAU INVALID MINUTES COLOUR SEED]
#   bash xtask/scripts/proto_on_prior.sh ../shared/peer ../shared/data/real out/s28-proto-our-prior
#
# COLOUR=1 (session 35's probe) also gives each plane a colour of its own: the U-Net's head
# gets a second output channel m (zero-initialised, like the first), and plane j's colour is
# the reference's moved towards the source warped onto that plane, ref + tanh(m) * (src - ref)
# where the source sees the plane, clamped to [0, 1]. Untrained, m = 0 and every colour is the
# reference's: the model is still exactly the sweep (the prototype's own identity check).
#
# SEED (default 0, the prototype's own) is its --seed: initialisation and triplet sampling.
#
# Needs python3 with torch. Writes OUT/train.log, OUT/test.log, OUT/test.json, OUT/ckpt.pt.
set -euo pipefail
if [ $# -lt 3 ]; then
  sed -n 2,16p "$0" >&2
  exit 2
fi
peer=$1 data=$2 out=$3 box=${4:-19} tau=${5:-0.005} invalid=${6:-0.25} minutes=${7:-44} colour=${8:-0} seed=${9:-0}
for f in torch_refine.py torch_sweep.py; do
  [ -f "$peer/$f" ] || { echo "error: $peer/$f not found (PEER_DIR must hold the prototype)" >&2; exit 1; }
done
for d in llff-6 strecha-2 re10k-3; do
  [ -d "$data/$d" ] || { echo "error: $data/$d not found (DATA_DIR must hold llff-6, strecha-2, re10k-3)" >&2; exit 1; }
done
if [ -e "$out/ckpt.pt" ]; then
  echo "error: $out/ckpt.pt exists; choose another OUT or remove it" >&2
  exit 1
fi
mkdir -p "$out/src"
cp "$peer/torch_refine.py" "$peer/torch_sweep.py" "$out/src/"
# Each substitution must hit exactly the line it names, or the peer changed and this stops.
sub() { # file, pattern, replacement
  python3 - "$out/src/$1" "$2" "$3" <<'EOF'
import sys
p, a, b = sys.argv[1:]
s = open(p).read()
n = s.count(a)
if n != 1:
    sys.exit(f"error: {a.splitlines()[0]!r}... found {n} times in {p} (expected once)")
open(p, "w").write(s.replace(a, b))
EOF
}
sub torch_refine.py "def sweep_alpha(Ir, ws, inside, tau=0.02, box=7):" "def sweep_alpha(Ir, ws, inside, tau=$tau, box=$box):"
sub torch_refine.py "c = torch.where(inside, c, torch.full_like(c, 0.5))" "c = torch.where(inside, c, torch.full_like(c, $invalid))"
sub torch_sweep.py "far=100.0, tau=0.02, box=7):" "far=100.0, tau=$tau, box=$box):"
sub torch_sweep.py "c = torch.where(ok, c, torch.full_like(c, 0.5))" "c = torch.where(ok, c, torch.full_like(c, $invalid))"
if [ "$colour" = 1 ]; then
  sub torch_refine.py "self.head = nn.Conv3d(w[0], 1, 3, 1, 1)" "self.head = nn.Conv3d(w[0], 2, 3, 1, 1)"
  sub torch_refine.py "    res = net(vol)[0, 0]
    alpha = torch.sigmoid(logit + res)
    alpha = torch.cat([torch.ones_like(alpha[:1]), alpha[1:]], 0)  # far plane forced opaque
    return a, alpha, res" "    out = net(vol)[0]; res = out[0]
    alpha = torch.sigmoid(logit + res)
    alpha = torch.cat([torch.ones_like(alpha[:1]), alpha[1:]], 0)  # far plane forced opaque
    mix = torch.tanh(out[1])[:, None] * inside[:, None].float()
    col = (Ir[None] + mix * (ws - Ir[None])).clamp(0, 1)
    return a, torch.cat([col, alpha[:, None]], 1), res"
  sub torch_refine.py "rgba = torch.cat([Ir[None].expand(D, -1, -1, -1), alpha[:, None]], 1)" "rgba = alpha if alpha.dim() == 4 else torch.cat([Ir[None].expand(D, -1, -1, -1), alpha[:, None]], 1)"
  sub torch_refine.py "alpha[1:], atol=1e-5), \"alphas differ from sweep\"" "alpha[1:, 3], atol=1e-5), \"alphas differ from sweep\"
        assert float((alpha[:, :3] - ref[0][None]).abs().max()) == 0.0, \"colours differ from the reference\""
fi
diff -u "$peer/torch_refine.py" "$out/src/torch_refine.py" > "$out/prior.diff" || true
diff -u "$peer/torch_sweep.py" "$out/src/torch_sweep.py" >> "$out/prior.diff" || true
python3 "$out/src/torch_refine.py" train --train_roots "$data/llff-6:train" "$data/strecha-2:train" \
  --val_root "$data/llff-6:train" --val_seq room --minutes "$minutes" --seed "$seed" --ckpt "$out/ckpt.pt" \
  2>&1 | tee "$out/train.log"
python3 "$out/src/torch_refine.py" test --test_root "$data/re10k-3:test" --ckpt "$out/ckpt.pt" \
  --out "$out/test.json" 2>&1 | tee "$out/test.log"
