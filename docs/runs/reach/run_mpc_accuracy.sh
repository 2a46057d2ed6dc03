#!/bin/bash
# How the FM's accuracy relates to FM-MPC's success (issue 17 item 2): exp 1 FMs of 1, 3
# and 10 cosine epochs on the paper exp 1 bag (30 epochs: run_mpc.sh), each driving
# 100 targets (seed 1) in process. Run after run_paper_im.sh (its bag and cache).
set -u
cd "$(dirname "$0")/../../.."
B=target/release/causal-arm
P=${P:-runs/reach_paper}
OUT=${OUT:-runs/reach_mpc}
mkdir -p "$OUT"
for e in 1 3 10; do
  $B train --bag $P/bags/paper_exp1 --model fm --profile paper --epochs $e --lr-schedule cosine \
    --max-folds 1 --seed 0 --cache $P/cache --out $P/models/fm_paper$e > $OUT/train_fm$e.log 2>&1
  grep -E "^fm/ef" $OUT/train_fm$e.log
  $B reach exp1 --controller fm-mpc --model-dir $P/models/fm_paper$e --targets 100 --seed 1 --in-process \
    --out $OUT/mpc_fm${e}_s1 > $OUT/mpc_fm${e}_s1.log 2>&1
  echo "fm $e epochs: $(tail -1 $OUT/mpc_fm${e}_s1.log)"
done
# The same 30-epoch FM trained on commanded deltas (--action commanded): its actions are what
# the controller sends, so its predictions are of the commands' outcomes.
$B train --bag $P/bags/paper_exp1 --model fm --profile paper --epochs 30 --lr-schedule cosine --action commanded \
  --max-folds 1 --seed 0 --cache $P/cache --out $P/models/fm_paper30_cmd > $OUT/train_fm30_cmd.log 2>&1
grep -E "^fm/ef" $OUT/train_fm30_cmd.log
$B reach exp1 --controller fm-mpc --model-dir $P/models/fm_paper30_cmd --targets 100 --seed 1 --in-process \
  --out $OUT/mpc_fm30cmd_s1 > $OUT/mpc_fm30cmd_s1.log 2>&1
echo "fm 30 epochs, commanded: $(tail -1 $OUT/mpc_fm30cmd_s1.log)"
