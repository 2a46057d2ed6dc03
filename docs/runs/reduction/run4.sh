#!/usr/bin/env bash
# Part 4: is the exp1 factored FM's ef head worse than the full FM's, or is it seed noise?
# Full FM and factored FM (256-wide heads), 60 cosine epochs, fold 1, paired by seed
# (the seed draws the folds, the weights and the shuffles; seed 0 is in run.sh/run2.sh).
source "$(dirname "$0")/_common.sh"
E1="--bag bags/paper_exp1 --lr-schedule cosine --max-folds 1 --epochs 60"
for seed in 1 2; do
  echo "==> $(date -u +%H:%M:%S) seed $seed"
  $B train $E1 --model fm --seed $seed --out models/paper_exp1_fm60_s$seed 2> "$LOG/exp1_fm60_s$seed.err" | tee "$LOG/exp1_fm60_s$seed.txt"
  $B train $E1 --model fm-factored --graph "$LOG/exp1_claims.json" --factored-hidden 256,256,256 \
    --seed $seed --out models/paper_exp1_factored256_s$seed 2> "$LOG/exp1_factored60_w256_s$seed.err" | tee "$LOG/exp1_factored60_w256_s$seed.txt"
done
# Does the ef head lose because a6 is cut from it, or because it no longer shares a network
# with θ? The same factored FM (seed 0) with a6 → ef added to the graph by hand.
$B train $E1 --model fm-factored --graph "$LOG/exp1_claims_a6_ef.json" --factored-hidden 256,256,256 \
  --out models/paper_exp1_factored256_a6ef 2> "$LOG/exp1_factored60_w256_a6ef.err" | tee "$LOG/exp1_factored60_w256_a6ef.txt"
echo "==> done"
