#!/usr/bin/env bash
# Part 5: fm-factored with auxiliary outputs (each head network also learns the features
# driven by a strict subset of its actions, e.g. θ0..θ5(t+1) for ef(t+1)), the default since
# this run. exp1: the three seeds of run4.sh, beside the full FM of run.sh/run4.sh.
# exp2: 30 epochs, 3×256 heads, beside the full FM and the plain factored FM of run2.sh.
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
[ -f bags/paper_exp1/metadata.yaml ] || $B generate exp1 --profile paper --seed 1 --out bags/paper_exp1
[ -f bags/paper_exp2_mws/metadata.yaml ] || $B generate exp2 --profile paper --seed 1 --out bags/paper_exp2_mws
E1="--bag bags/paper_exp1 --lr-schedule cosine --max-folds 1 --epochs 60 --model fm-factored --graph $LOG/exp1_claims.json --factored-hidden 256,256,256"
train models/paper_exp1_factored256_aux_s0 exp1_factored60_w256_aux_s0 $E1 --seed 0
train models/paper_exp2_factored256_aux exp2_factored30_w256_aux --bag bags/paper_exp2_mws \
  --lr-schedule cosine --max-folds 1 --epochs 30 --model fm-factored --graph $LOG/exp2_claims.json \
  --factored-hidden 256,256,256
for seed in 1 2; do
  train models/paper_exp1_factored256_aux_s$seed exp1_factored60_w256_aux_s$seed $E1 --seed $seed
done
step done
