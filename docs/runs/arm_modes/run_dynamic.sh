#!/bin/bash
# Issue 18: the paper-size exp2 bag of the dynamic arm (seed 1, 2 shards: ~1,100 steps/s a
# core), and its statistics.
set -e
B=$PWD/target/release/causal-arm  # run from the repository root; the release build of c8e93fb
cd docs/runs/arm_modes  # bags and models are written beside the scripts (not committed)
# (it waited here for run.sh's statistics of the kinematic bag to finish)
start=$(date +%s)
$B generate exp2 --profile paper --seed 1 --arm dynamic --shards 2 --overwrite --out bag_dynamic > gen_dynamic.log 2>&1
echo "dynamic generated in $(( $(date +%s) - start )) s (2 shards)" >> times.txt
$B bag stats bag_dynamic > stats_dynamic.json 2> stats_dynamic.err
echo done >> times.txt
