#!/bin/bash
# FM-MPC moves the cube to a spot on the table (issue 17 item 2), 50 trials per seed, with
# the exp 2 FM of run_exp2.sh (400 episodes, 30 cosine epochs, fold 1): over DDS (reacher
# node with task:=place, trainer node serving the FM) and in process, to compare.
set -u
cd "$(dirname "$0")/../../.."
B=target/release/causal-arm
M=${M:-runs/exp2_reach/models_fm}
OUT=${OUT:-runs/place}
mkdir -p "$OUT"
for s in 1 2 3; do
  tests/netns-run $B place --trials 50 --seed $s --model-dir $M --out $OUT/place_s$s --overwrite > $OUT/place_s$s.log 2>&1
  echo "seed $s over DDS rc=$? $(tail -1 $OUT/place_s$s.log)"
  $B place --trials 50 --seed $s --model-dir $M --in-process --out $OUT/place_s${s}_proc > $OUT/place_s${s}_proc.log 2>&1
  echo "seed $s in process rc=$? $(tail -1 $OUT/place_s${s}_proc.log)"
done
