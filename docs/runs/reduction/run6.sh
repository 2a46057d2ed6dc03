#!/usr/bin/env bash
# Part 6: is the exp2 factored FM with auxiliary outputs worse than the full FM on obj pos
# and obj rot (run5.sh, seed 0), or is it seed noise? Full FM and fm-factored (3×256,
# auxiliary outputs), 30 cosine epochs, fold 1, paired by seed (seed = folds, weights, shuffles).
source "$(dirname "$0")/_common.sh"
E2="--bag bags/paper_exp2_mws --lr-schedule cosine --max-folds 1 --epochs 30"
for seed in 1 2; do
  train models/paper_exp2_fm30_s$seed exp2_fm30_s$seed $E2 --model fm --seed $seed
  train models/paper_exp2_factored256_aux_s$seed exp2_factored30_w256_aux_s$seed $E2 --model fm-factored \
    --graph $LOG/exp2_claims.json --factored-hidden 256,256,256 --seed $seed
done
step done
