#!/usr/bin/env bash
# Part 8: the exp2 fm-factored `--factored-auxiliary auto` run of run7.sh (seed 0) on
# seeds 1 and 2, beside run6.sh's full FMs of the same seeds, to tell whether obj rot's
# +2.3 % on seed 0 is the method or the seed.
source "$(dirname "$0")/_common.sh"
# Only the exp2 bag is read here.
[ -f bags/paper_exp2_mws/metadata.yaml ] || $B generate exp2 --profile paper --seed 1 --out bags/paper_exp2_mws
E2="--bag bags/paper_exp2_mws --lr-schedule cosine --max-folds 1 --epochs 30"
for seed in ${SEEDS:-1 2}; do  # SEEDS=2 reruns one seed
  train models/paper_exp2_factored256_auto_s$seed exp2_factored30_w256_auto_s$seed $E2 --model fm-factored \
    --graph $LOG/exp2_claims.json --factored-hidden 256,256,256 --factored-auxiliary auto --seed $seed
done
step done
