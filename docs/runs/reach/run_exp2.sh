#!/bin/bash
# Reaching in exp 2 (issue 17): targets above the table, 100 per seed, over DDS, with the
# exp 2 IM and FM trained on a 400-episode exp 2 bag (30 cosine epochs, fold 1 of 5), the
# Jacobian baseline and babbling. Then the same runs in process, to compare.
# Run after `cargo build --release`.
set -u
cd "$(dirname "$0")/../../.."
B=target/release/causal-arm
R=${R:-runs/exp2_reach}
OUT=${OUT:-runs/reach_exp2}
mkdir -p "$OUT"
if [ ! -d "$R/models_im" ]; then
  $B generate exp2 --episodes 400 --seed 0 --out $R/bag --overwrite
  for m in fm im-mono; do
    $B train --bag $R/bag --model $m --profile paper --epochs 30 --lr-schedule cosine --max-folds 1 \
      --seed 0 --cache $R/cache --out $R/models_${m%-mono}
  done
fi
for s in 1 2 3; do
  for c in im fm-mpc jacobian random; do
    case $c in im) M=$R/models_im;; *) M=$R/models_fm;; esac
    tests/netns-run $B reach exp2 --controller $c --model-dir $M --targets 100 --seed $s \
      --out $OUT/${c}_s$s --overwrite > $OUT/${c}_s$s.log 2>&1
    echo "seed $s $c over DDS rc=$? $(tail -1 $OUT/${c}_s$s.log)"
    $B reach exp2 --controller $c --model-dir $M --targets 100 --seed $s --in-process \
      --out $OUT/${c}_s${s}_proc > $OUT/${c}_s${s}_proc.log 2>&1
    echo "seed $s $c in process rc=$? $(tail -1 $OUT/${c}_s${s}_proc.log)"
  done
done
