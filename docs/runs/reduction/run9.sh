#!/usr/bin/env bash
# Part 9: exp2 fm-factored `--factored-auxiliary auto` after the full FM joined the
# comparison: each head's best candidate must beat the full FM's head on the validation
# rows by more than two batch-means standard errors, or the head keeps the full FM's own
# network (fitted on all training rows: the `--model fm` run of run6.sh, same seed). Beside
# run6.sh's full FMs of the same seeds.
source "$(dirname "$0")/_common.sh"
[ -f bags/paper_exp2_mws/metadata.yaml ] || $B generate exp2 --profile paper --seed 1 --out bags/paper_exp2_mws
E2="--bag bags/paper_exp2_mws --lr-schedule cosine --max-folds 1 --epochs 30"
for seed in ${SEEDS:-0 1 2}; do
  train models/paper_exp2_factored256_vsfull_s$seed exp2_factored30_w256_vsfull_s$seed $E2 --model fm-factored \
    --graph $LOG/exp2_claims.json --factored-hidden 256,256,256 --factored-auxiliary auto --seed $seed
done
step done
