#!/usr/bin/env bash
# Part 5: fm-factored with auxiliary outputs (each head network also learns the features
# driven by a strict subset of its actions, e.g. θ0..θ5(t+1) for ef(t+1)), the default since
# this run. exp1: the three seeds of run4.sh, beside the full FM of run.sh/run4.sh.
# exp2: 30 epochs, 3×256 heads, beside the full FM and the plain factored FM of run2.sh.
source "$(dirname "$0")/_common.sh"
paper_bags
E1="--bag bags/paper_exp1 --lr-schedule cosine --max-folds 1 --epochs 60 --model fm-factored --graph $LOG/exp1_claims.json --factored-hidden 256,256,256"
train models/paper_exp1_factored256_aux_s0 exp1_factored60_w256_aux_s0 $E1 --seed 0
train models/paper_exp2_factored256_aux exp2_factored30_w256_aux --bag bags/paper_exp2_mws \
  --lr-schedule cosine --max-folds 1 --epochs 30 --model fm-factored --graph $LOG/exp2_claims.json \
  --factored-hidden 256,256,256
for seed in 1 2; do
  train models/paper_exp1_factored256_aux_s$seed exp1_factored60_w256_aux_s$seed $E1 --seed $seed
done
step done
