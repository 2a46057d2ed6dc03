#!/usr/bin/env bash
# Part 6: is the exp2 factored FM with auxiliary outputs worse than the full FM on obj pos
# and obj rot (run5.sh, seed 0), or is it seed noise? Full FM and fm-factored (3×256,
# auxiliary outputs), 30 cosine epochs, fold 1, paired by seed (seed = folds, weights, shuffles).
set -euo pipefail
cd "$(dirname "$0")/../../.."
B=${CAUSAL_ARM:-target/release/causal-arm}
LOG=docs/runs/reduction
step() { echo "==> $(date -u +%H:%M:%S) $*"; }
train() { # out, log name, args...
  local out=$1 name=$2; shift 2
  step "train $name"
  $B train "$@" --out "$out" 2> "$LOG/$name.err" | tee "$LOG/$name.txt"
  cp "$out/metrics.json" "$LOG/$name.metrics.json"
}
E2="--bag bags/paper_exp2_mws --lr-schedule cosine --max-folds 1 --epochs 30"
for seed in 1 2; do
  train models/paper_exp2_fm30_s$seed exp2_fm30_s$seed $E2 --model fm --seed $seed
  train models/paper_exp2_factored256_aux_s$seed exp2_factored30_w256_aux_s$seed $E2 --model fm-factored \
    --graph $LOG/exp2_claims.json --factored-hidden 256,256,256 --seed $seed
done
step done
