#!/bin/bash
# Issue 18: the paper-size exp1 bag of the dynamic arm (seed 0, as paper_exp1; 2 shards),
# its statistics, and the exp1 models with the summary rows' protocols, fold 1 of 5.
set -e
B=$PWD/target/release/causal-arm  # run from the repository root; the release build of df42cba
cd docs/runs/arm_modes  # bags and models are written beside the scripts (not committed)
t() { echo "$1 in $(( $(date +%s) - $2 )) s" >> times.txt; }
s=$(date +%s); $B generate exp1 --profile paper --seed 0 --arm dynamic --shards 2 --overwrite --out bag_exp1_dynamic > gen_exp1_dynamic.log 2>&1; t "exp1 dynamic generated (2 shards)" $s
$B bag stats bag_exp1_dynamic > stats_exp1_dynamic.json 2> stats_exp1_dynamic.err
s=$(date +%s); $B train --bag bag_exp1_dynamic --model fm --epochs 60 --folds 5 --max-folds 1 --cache cache --out models_exp1_fm > train_exp1_fm.log 2>&1; t "exp1 FM (60 epochs, constant) trained" $s
s=$(date +%s); $B train --bag bag_exp1_dynamic --model im-mono --epochs 100 --folds 5 --max-folds 1 --lr-schedule cosine --cache cache --out models_exp1_im > train_exp1_im.log 2>&1; t "exp1 IM mono (100 cosine) trained" $s
s=$(date +%s); $B train --bag bag_exp1_dynamic --model im-pre --epochs 100 --folds 5 --max-folds 1 --lr-schedule cosine --cache cache --out models_exp1_pre > train_exp1_pre.log 2>&1; t "exp1 base IM + pre-network (100 cosine) trained" $s
echo exp1-done >> times.txt
