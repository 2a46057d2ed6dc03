#!/usr/bin/env bash
# Issue 13, item 5 (state-space reduction) and the default method on the paper-profile
# bags, part 1 (run2.sh is part 2): the runs behind docs/RESULTS.md "State-space reduction". Each step logs into this
# directory; models go to models/ (not committed; their metrics.json are copied here).
source "$(dirname "$0")/_common.sh"
paper_bags

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
