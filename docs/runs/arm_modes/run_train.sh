#!/bin/bash
# Issue 18: the exp2 FM of the dynamic arm's paper-size bag, with the protocol of the
# kinematic row in docs/RESULTS.md (100 cosine epochs, fold 1 of 5, batch 256, lr 1e-3).
set -e
B=$PWD/target/release/causal-arm  # run from the repository root; the release build of c8e93fb
cd docs/runs/arm_modes  # bags and models are written beside the scripts (not committed)
until grep -q '^done' times.txt 2>/dev/null; do sleep 10; done
start=$(date +%s)
$B train --bag bag_dynamic --model fm --epochs 100 --folds 5 --max-folds 1 --lr-schedule cosine \
  --eval-every 25 --cache cache --out models_fm_dynamic > train_fm_dynamic.log 2>&1
echo "exp2 FM dynamic trained in $(( $(date +%s) - start )) s" >> times.txt
