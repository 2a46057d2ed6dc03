#!/usr/bin/env bash
# Issue 13, item 5 (state-space reduction) and the default method on the paper-profile
# bags: the runs behind docs/RESULTS.md "State-space reduction". Each step logs into this
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

# exp2 (default babbling): full FM, explanation, reduced FM, factored FM, full and reduced IM.
E2="--bag bags/paper_exp2_mws --lr-schedule cosine --max-folds 1"
train models/paper_exp2_fm30 exp2_fm30 $E2 --model fm --epochs 30
step "explain exp2"
$B explain --model models/paper_exp2_fm30 --bag bags/paper_exp2_mws --method kernel --no-pair-plots \
  --truth docs/truth/paper_exp2_mws 2> "$LOG/exp2_explain.err" | tee "$LOG/exp2_explain.txt"
G2=models/paper_exp2_fm30/explain-kernel/claims.json
cp "$G2" "$LOG/exp2_claims.json"
train models/paper_exp2_reduced exp2_fm30_reduced $E2 --model fm --graph "$G2" --epochs 30
train models/paper_exp2_factored exp2_factored30 $E2 --model fm-factored --graph "$G2" --epochs 30
train models/paper_exp2_im20 exp2_im20 $E2 --model im-mono --epochs 20
train models/paper_exp2_im20_reduced exp2_im20_reduced $E2 --model im-mono --graph "$G2" --epochs 20
step "done"
