#!/usr/bin/env bash
# Part 7: fm-factored with `--factored-auxiliary auto` (the default since this run): per head,
# one network per distinct output set of none / upstream / determined, fitted on the first
# 95 % of the training rows and compared on the last 5 % (never the test fold); the best
# one is kept. exp1: the three seeds of run4.sh/run5.sh; exp2: seed 0 of run5.sh, then the
# reduced unfactored FM (which `determined` equals for a head driven by every action) on
# seeds 1 and 2 beside run6.sh's full FMs (seed 2 was stopped unfinished at the end of
# the session).
source "$(dirname "$0")/_common.sh"
paper_bags
E1="--bag bags/paper_exp1 --lr-schedule cosine --max-folds 1 --epochs 60 --model fm-factored --graph $LOG/exp1_claims.json --factored-hidden 256,256,256 --factored-auxiliary auto"
for seed in 0 1 2; do
  train models/paper_exp1_factored256_auto_s$seed exp1_factored60_w256_auto_s$seed $E1 --seed $seed
done
E2="--bag bags/paper_exp2_mws --lr-schedule cosine --max-folds 1 --epochs 30"
train models/paper_exp2_factored256_auto exp2_factored30_w256_auto $E2 --model fm-factored \
  --graph $LOG/exp2_claims.json --factored-hidden 256,256,256 --factored-auxiliary auto --seed 0
for seed in 1 2; do
  train models/paper_exp2_fm30_reduced_s$seed exp2_fm30_reduced_s$seed $E2 --model fm \
    --graph $LOG/exp2_claims.json --seed $seed
done
step done
