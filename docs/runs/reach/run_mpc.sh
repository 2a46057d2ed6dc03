#!/bin/bash
# FM-MPC reaching (issue 17 item 2): the FM of 30 paper-profile epochs on the paper exp1 bag
# (run_paper_im.sh's bag), 100 targets per seed over DDS, and a horizon ablation in process.
# Run after `cargo build --release`; M = the FM's model directory.
set -u
cd "$(dirname "$0")/../../.."
B=target/release/causal-arm
M=${M:-runs/reach_paper/models/fm_paper30}
OUT=${OUT:-runs/reach_mpc}
mkdir -p "$OUT"
for s in 1 2 3; do
  tests/netns-run $B reach exp1 --controller fm-mpc --model-dir $M --targets 100 --seed $s \
    --out $OUT/mpc_s$s --overwrite > $OUT/mpc_s$s.log 2>&1
  echo "seed $s fm-mpc over DDS rc=$? $(tail -1 $OUT/mpc_s$s.log)"
  $B reach exp1 --controller fm-mpc --model-dir $M --targets 100 --seed $s --in-process \
    --out $OUT/mpc_s${s}_proc > $OUT/mpc_s${s}_proc.log 2>&1
  echo "seed $s fm-mpc in process rc=$? $(tail -1 $OUT/mpc_s${s}_proc.log)"
done
for h in 3 5; do
  $B reach exp1 --controller fm-mpc --model-dir $M --targets 100 --seed 1 --horizon $h --in-process \
    --out $OUT/mpc_h${h}_s1 > $OUT/mpc_h${h}_s1.log 2>&1
  echo "seed 1 horizon $h in process rc=$? $(tail -1 $OUT/mpc_h${h}_s1.log)"
done
