#!/bin/bash
# FM-MPC moves the cube to a spot on the table (issue 17 item 2), 50 trials per seed, with
# the exp 2 FM of run_exp2.sh (400 episodes, 30 cosine epochs, fold 1). In process.
set -u
cd "$(dirname "$0")/../../.."
B=target/release/causal-arm
M=${M:-runs/exp2_reach/models_fm}
OUT=${OUT:-runs/place}
mkdir -p "$OUT"
for s in 1 2 3; do
  $B place --trials 50 --seed $s --model-dir $M --out $OUT/place_s$s > $OUT/place_s$s.log 2>&1
  echo "seed $s rc=$? $(tail -1 $OUT/place_s$s.log)"
done
