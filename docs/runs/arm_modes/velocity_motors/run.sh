#!/bin/bash
# Issue 18, the dynamic arm with velocity motors (PyBullet's POSITION_CONTROL: velocity target
# within the URDF velocity limit, torque within the URDF effort). Everything measured on the
# spring motors before (../run_dynamic.sh, ../run_train.sh, ../run_exp1.sh) again, plus the
# truth scores and the exp2 IM:
# 1. the paper-size exp2 bag (seed 1, default babbling, 2 shards) and its statistics;
# 2. the intervention truth from its shard 0 (the protocol of docs/truth/paper_exp2_mws);
# 3. the exp2 FM at 30 cosine epochs (fold 1 of 5) and its `kernel+cai` explanation scored
#    against that truth;
# 4. the exp2 IM at 100 cosine epochs (fold 1);
# 5. the paper-size exp1 bag (seed 0, 2 shards), its statistics and the exp1 models with
#    the summary rows' protocols (fold 1).
# Stop 31 ran steps 1-4 (times.txt); stop 32 ran steps 1-5 again after turning rapier's
# contact recycling off in the dynamic world (the 11.1 mm state) and exempting links 5 and 7
# from colliding (their cylinders stalled the wrist at 1.74 rad); stats_exp2_fresh_contacts_only.json
# is the bag with only the first change.
set -e
B=${B:-$PWD/target/release/causal-arm}  # run from the repository root
T=$PWD/docs/truth/paper_exp2_dynamic
cd docs/runs/arm_modes/velocity_motors  # bags and models are written here (not committed)
t() { echo "$(date +%T) $1 in $(( $(date +%s) - $2 )) s" >> times.txt; }
s=$(date +%s); $B generate exp2 --profile paper --seed 1 --arm dynamic --shards 2 --overwrite --out bag_exp2 > gen_exp2.log 2>&1; t "exp2 generated (2 shards)" $s
$B bag stats bag_exp2 > stats_exp2.json 2> stats_exp2.err
s=$(date +%s); $B intervene exp2 --bag bag_exp2/shard-0 --states 2000 --horizon 10 --out "$T" > intervene_exp2.log 2>&1; t "exp2 truth (2,000 states, horizon 10)" $s
s=$(date +%s); $B train --bag bag_exp2 --model fm --epochs 30 --folds 5 --max-folds 1 --lr-schedule cosine --cache cache --out models_exp2_fm30 > train_exp2_fm30.log 2>&1; t "exp2 FM (30 cosine) trained" $s
s=$(date +%s); $B explain --model models_exp2_fm30 --bag bag_exp2 --method kernel --no-pair-plots --truth "$T" > explain_exp2_fm30.txt 2> explain_exp2_fm30.err; t "exp2 FM explained (kernel+cai)" $s
s=$(date +%s); $B train --bag bag_exp2 --model im-mono --epochs 100 --folds 5 --max-folds 1 --lr-schedule cosine --eval-every 25 --cache cache --out models_exp2_im100 > train_exp2_im100.log 2>&1; t "exp2 IM (100 cosine) trained" $s
s=$(date +%s); $B generate exp1 --profile paper --seed 0 --arm dynamic --shards 2 --overwrite --out bag_exp1 > gen_exp1.log 2>&1; t "exp1 generated (2 shards)" $s
$B bag stats bag_exp1 > stats_exp1.json 2> stats_exp1.err
s=$(date +%s); $B train --bag bag_exp1 --model fm --epochs 60 --folds 5 --max-folds 1 --cache cache --out models_exp1_fm > train_exp1_fm.log 2>&1; t "exp1 FM (60 epochs, constant) trained" $s
s=$(date +%s); $B train --bag bag_exp1 --model im-mono --epochs 100 --folds 5 --max-folds 1 --lr-schedule cosine --cache cache --out models_exp1_im > train_exp1_im.log 2>&1; t "exp1 IM mono (100 cosine) trained" $s
s=$(date +%s); $B train --bag bag_exp1 --model im-pre --epochs 100 --folds 5 --max-folds 1 --lr-schedule cosine --cache cache --out models_exp1_pre > train_exp1_pre.log 2>&1; t "exp1 base IM + pre-network (100 cosine) trained" $s
echo "$(date +%T) done" >> times.txt
