#!/bin/bash
# Issue 18: the exp2 IM (100 cosine epochs, fold 1 of 5) on the kinematic arm's paper-size exp2
# bag (seed 1, default babbling), the column beside the dynamic arm's in docs/RESULTS.md.
set -e
B=${B:-$PWD/target/release/causal-arm}  # run from the repository root
cd docs/runs/arm_modes  # bags and models are written beside the scripts (not committed)
step() { echo "$(date +%T) $*" >> times_truth_im.txt; }
s=$(date +%s)
$B generate exp2 --profile paper --seed 1 --arm kinematic --overwrite --out bag_kinematic > gen_kinematic2.log 2>&1
step "generated kinematic in $(( $(date +%s) - s )) s"
s=$(date +%s)
$B train --bag bag_kinematic --model im-mono --epochs 100 --folds 5 --max-folds 1 --lr-schedule cosine \
  --eval-every 25 --cache cache --out models_im100_kinematic > train_im100_kinematic.log 2>&1
step "exp2 IM 100 kinematic trained in $(( $(date +%s) - s )) s"
