#!/usr/bin/env bash
# Second part of the reduction runs: the exp2 FM at 100 cosine epochs (the graph is read
# from its explanation), then the reduced and factored FMs and the IMs at the epochs of
# the full runs of run.sh; and the exp1 factored FM with 256-wide heads.
source "$(dirname "$0")/_common.sh"
E2="--bag bags/paper_exp2_mws --lr-schedule cosine --max-folds 1"
train models/paper_exp2_fm100 exp2_fm100 $E2 --model fm --epochs 100
step "explain exp2 (100-epoch FM)"
$B explain --model models/paper_exp2_fm100 --bag bags/paper_exp2_mws --method kernel --no-pair-plots \
  --truth docs/truth/paper_exp2_mws 2> "$LOG/exp2_fm100_explain.err" | tee "$LOG/exp2_fm100_explain.txt"
G2=models/paper_exp2_fm100/explain-kernel/claims.json
cp "$G2" "$LOG/exp2_claims.json"
train models/paper_exp2_reduced exp2_fm30_reduced $E2 --model fm --graph "$G2" --epochs 30
train models/paper_exp2_factored exp2_factored30 $E2 --model fm-factored --graph "$G2" --epochs 30
train models/paper_exp2_im20 exp2_im20 $E2 --model im-mono --epochs 20
train models/paper_exp2_im20_reduced exp2_im20_reduced $E2 --model im-mono --graph "$G2" --epochs 20
E1="--bag bags/paper_exp1 --lr-schedule cosine --max-folds 1"
train models/paper_exp1_factored256 exp1_factored60_w256 $E1 --model fm-factored \
  --graph "$LOG/exp1_claims.json" --epochs 60 --factored-hidden 256,256,256
step "done"
