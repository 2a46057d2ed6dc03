#!/bin/bash
# Issue 18: paper-size exp2 bags of both arm modes (seed 1, 2 shards), and their statistics.
set -e
B=$PWD/target/release/causal-arm  # run from the repository root; the release build of c8e93fb
cd docs/runs/arm_modes  # bags and models are written beside the scripts (not committed)
# (stopped after the kinematic arm: run_dynamic.sh made the dynamic bag with 2 shards)
for arm in kinematic dynamic; do
  start=$(date +%s)
  $B generate exp2 --profile paper --seed 1 --arm $arm --overwrite --out bag_$arm > gen_$arm.log 2>&1
  echo "$arm generated in $(( $(date +%s) - start )) s" >> times.txt
  $B bag stats bag_$arm > stats_$arm.json 2> stats_$arm.err
done
echo done >> times.txt
