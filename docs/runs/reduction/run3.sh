#!/usr/bin/env bash
# Part 3: the figures of the exp2 claims beside the truth (Deep and Kernel SHAP runs of the
# 100-epoch FM of run2.sh), the multi-step edges of both experiments through the chained FM
# (k = 1..10) against the truth's horizons, and the exp2 factored FM with 256-wide heads.
source "$(dirname "$0")/_common.sh"
for method in deep kernel; do
  step "explain exp2 $method"
  $B explain --model models/paper_exp2_fm100 --bag bags/paper_exp2_mws --method $method --no-pair-plots \
    --truth docs/truth/paper_exp2_mws 2> "$LOG/exp2_fm100_explain_$method.err" | tee "$LOG/exp2_fm100_explain_$method.txt"
done
mkdir -p docs/claims
D=models/paper_exp2_fm100
cp $D/explain-kernel/verdicts_heatmap.png docs/claims/exp2_kernel_cai.png
cp $D/explain-kernel/verdicts_kernel.png docs/claims/exp2_kernel.png
cp $D/explain-kernel/verdicts_cai_err.png docs/claims/exp2_cai.png
cp $D/explain-deep/verdicts_deep.png docs/claims/exp2_deep.png
step "multistep exp2"
$B explain --model models/paper_exp2_fm100 --bag bags/paper_exp2_mws --method cai --horizon 10 \
  --truth docs/truth/paper_exp2_mws 2> "$LOG/exp2_multistep.err" | tee "$LOG/exp2_multistep.txt"
step "multistep exp1"
$B explain --model models/paper_exp1_fm60 --bag bags/paper_exp1 --method cai --horizon 10 \
  --truth docs/truth/paper_exp1 2> "$LOG/exp1_multistep.err" | tee "$LOG/exp1_multistep.txt"
for e in exp1 exp2; do
  M=models/paper_${e}_fm60; [ $e = exp2 ] && M=models/paper_exp2_fm100
  cp $M/explain-cai-h10/multistep_scores.png docs/claims/${e}_multistep_scores.png
  cp $M/explain-cai-h10/multistep_a_mgt_o_z.png docs/claims/${e}_multistep_a_mgt_o_z.png 2>/dev/null || true
done
step "train exp2_factored30_w256"
$B train --bag bags/paper_exp2_mws --lr-schedule cosine --max-folds 1 --model fm-factored \
  --graph "$LOG/exp2_claims.json" --epochs 30 --factored-hidden 256,256,256 \
  --out models/paper_exp2_factored256 2> "$LOG/exp2_factored30_w256.err" | tee "$LOG/exp2_factored30_w256.txt"
cp models/paper_exp2_factored256/metrics.json "$LOG/exp2_factored30_w256.metrics.json"
step "done"
