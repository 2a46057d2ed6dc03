#!/bin/bash
# The dynamic arm's verdicts against truths at four effect sizes (run from the repo root).
set -e
B=${CAUSAL_ARM_BIN:-target/release/causal-arm}; D=target/dyn/exp2_50k
for action in realized commanded; do
  $B discover --bag $D/bag --action $action --out $D/discover_$action > /dev/null
  for K in 0 0.01 0.03 0.1; do
    echo "== data test, $action actions, truth K = $K"
    $B score --claims $D/discover_$action/claims.json --truth $D/truth_k$K --out $D/discover_$action/scores_k$K.json | grep -E "^(method|data|granger-x) +(context|all) +(block|all)"
  done
done
for budget in quick e30; do
  extra=""; [ $budget = e30 ] && extra="--epochs 30 --lr-schedule cosine"
  [ -f $D/model-$budget/fm.safetensors ] || $B train --bag $D/bag --model fm --profile quick --max-folds 1 --out $D/model-$budget $extra > /dev/null
  $B explain --model $D/model-$budget --bag $D/bag --method kernel --no-pair-plots > /dev/null
  for K in 0 0.01 0.03 0.1; do
    echo "== default (kernel+cai+data), $budget FM on commanded actions, truth K = $K"
    $B score --claims $D/model-$budget/explain-kernel/claims.json --truth $D/truth_k$K --out $D/model-$budget/explain-kernel/scores_k$K.json | grep -E "^(method|kernel\+cai\+data|cai/err|data) +(context|all) +(block|all)"
  done
done
