#!/bin/bash
# The paper-profile exp1 IM and the reach runs of exp1_100_targets.txt (part C).
# Run from the repository root after `cargo build --release`; writes under $OUT.
set -euo pipefail
B=${B:-target/release/causal-arm}
OUT=${OUT:-runs/reach_paper}
mkdir -p "$OUT"
$B generate exp1 --profile paper --seed 0 --out "$OUT/bags/paper_exp1" --overwrite
$B train --bag "$OUT/bags/paper_exp1" --model im-mono --profile paper --epochs 100 \
  --lr-schedule cosine --max-folds 1 --seed 0 --out "$OUT/models/im_paper"
for seed in 1 2 3; do
  for c in im jacobian random; do
    $B reach exp1 --controller "$c" --model-dir "$OUT/models/im_paper" --targets 100 \
      --seed "$seed" --step 0.1 --out "$OUT/reach_${c}_s$seed"
  done
done
