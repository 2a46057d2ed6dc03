#!/bin/bash
# Issue 18, after run.sh: the dynamic arm's intervention truth with an effect size of 0.01
# (an effect counts above 1 % of the feature's one-step std, the scale of the explainer's
# default rule: mean |phi| >= 1 % of the feature's change spread), the same states as
# docs/truth/paper_exp2_dynamic, and the exp2 FM's explanation scored against it.
set -e
B=${B:-$PWD/target/release/causal-arm}  # run from the repository root
T=$PWD/docs/truth/paper_exp2_dynamic_effect_size
cd docs/runs/arm_modes/velocity_motors
t() { echo "$(date +%T) $1 in $(( $(date +%s) - $2 )) s" >> times.txt; }
s=$(date +%s); $B intervene exp2 --bag bag_exp2/shard-0 --states 2000 --horizon 10 --effect-size 0.01 --out "$T" > intervene_exp2_effect_size.log 2>&1; t "exp2 truth, effect size 0.01" $s
s=$(date +%s); $B explain --model models_exp2_fm30 --bag bag_exp2 --method kernel --no-pair-plots --truth "$T" --out explain_effect_size > explain_exp2_fm30_effect_size.txt 2> explain_exp2_fm30_effect_size.err; t "exp2 FM explained against it" $s
