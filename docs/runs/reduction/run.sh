#!/usr/bin/env bash
# Issue 13, item 5 (state-space reduction) and the default method on the paper-profile
# bags, part 1 (run2.sh is part 2): the runs behind docs/RESULTS.md "State-space reduction". Each step logs into this
# directory; models go to models/ (not committed; their metrics.json are copied here).
set -euo pipefail
cd "$(dirname "$0")/../../.."
B=${CAUSAL_ARM:-target/release/causal-arm}
LOG=docs/runs/reduction
step() { echo "==> $(date -u +%H:%M:%S) $*"; }
train() { # out, log name, args...
  local out=$1 name=$2; shift 2
  step "train $name"
  $B train "$@" --out "$out" 2> "$LOG/$name.err" | tee "$LOG/$name.txt"
  cp "$out/metrics.json" "$LOG/$name.metrics.json"
}
[ -f bags/paper_exp1/metadata.yaml ] || $B generate exp1 --profile paper --seed 1 --out bags/paper_exp1
[ -f bags/paper_exp2_mws/metadata.yaml ] || $B generate exp2 --profile paper --seed 1 --out bags/paper_exp2_mws

# exp1: full FM, its explanation scored against the truth, then the factored FM.
E1="--bag bags/paper_exp1 --lr-schedule cosine --max-folds 1"
train models/paper_exp1_fm60 exp1_fm60 $E1 --model fm --epochs 60
step "explain exp1"
$B explain --model models/paper_exp1_fm60 --bag bags/paper_exp1 --method kernel --no-pair-plots \
  --truth docs/truth/paper_exp1 2> "$LOG/exp1_explain.err" | tee "$LOG/exp1_explain.txt"
G1=models/paper_exp1_fm60/explain-kernel/claims.json
cp "$G1" "$LOG/exp1_claims.json"
train models/paper_exp1_factored exp1_factored60 $E1 --model fm-factored --graph "$G1" --epochs 60

# exp2 (default babbling): the full FM at 30 epochs and its explanation (run2.sh goes on).
E2="--bag bags/paper_exp2_mws --lr-schedule cosine --max-folds 1"
train models/paper_exp2_fm30 exp2_fm30 $E2 --model fm --epochs 30
step "explain exp2"
$B explain --model models/paper_exp2_fm30 --bag bags/paper_exp2_mws --method kernel --no-pair-plots \
  --truth docs/truth/paper_exp2_mws 2> "$LOG/exp2_fm30_explain.err" | tee "$LOG/exp2_fm30_explain.txt"
cp models/paper_exp2_fm30/explain-kernel/claims.json "$LOG/exp2_fm30_claims.json"
step "done"
