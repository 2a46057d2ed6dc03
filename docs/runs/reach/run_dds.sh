#!/bin/bash
# Run from anywhere after `cargo build --release`; M = the IM of run_paper_im.sh.
# Reach over DDS, 100 targets per seed, every controller at --step 0.1 (issue 17 must-show).
set -u
cd "$(dirname "$0")/../../.."
mkdir -p "${OUT:-runs/reach_dds}"
B=target/release/causal-arm
M=${M:-runs/reach_paper/models/im_paper}
for s in 1 2 3; do
  for c in im jacobian random; do
    tests/netns-run $B reach exp1 --controller $c --model-dir $M --targets 100 --seed $s --step 0.1 \
      --out ${OUT:-runs/reach_dds}/${c}_s$s --overwrite > ${OUT:-runs/reach_dds}/${c}_s$s.log 2>&1
    echo "seed $s $c rc=$? $(tail -1 ${OUT:-runs/reach_dds}/${c}_s$s.log)"
  done
done
