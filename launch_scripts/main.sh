#!/usr/bin/env bash
# The README's main job, end to end on the embedded default (urdf/iiwa14_magnet.urdf).
# It grows with the project; today it builds the release binaries, shows the arm's
# kinematics, runs both experiments' data-generation graphs (simulator, babbler and
# recorder as three ROS 2 node processes over DDS, inside a private loopback-only network
# namespace) on the quick profile, cross-validates the paper's models on those bags,
# intervenes in the simulator on states of both bags for the causal ground truth,
# runs the exp1 mental simulation, has the trainer node train an FM from a bag and asks it
# for a prediction over DDS, explains
# the exp2 forward model with Deep SHAP and Kernel SHAP (heat map, partial dependence plots,
# relevance report) and reads the explainer node's latched relevance report over DDS.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --locked --workspace --bins
BIN=target/release/causal-arm

echo "==> forward kinematics of the embedded URDF (ef frame, world frame)"
$BIN fk --joints 0,0.5,0,-1.2,0,0.8,0
echo "==> inverse kinematics to a point above the table, tool pointing down"
$BIN ik --position 0.6,0.0,0.3 --down --seed 1

echo "==> experiment 1 and 2 datasets through the ROS 2 graph (quick profile)"
tests/netns-run env ROS_DOMAIN_ID="${ROS_DOMAIN_ID:-7}" RUST_LOG="${RUST_LOG:-error}" \
  $BIN launch exp1 --profile quick --seed 1 --out bags/quick_exp1 --overwrite
tests/netns-run env ROS_DOMAIN_ID="${ROS_DOMAIN_ID:-7}" RUST_LOG="${RUST_LOG:-error}" \
  $BIN launch exp2 --profile quick --seed 1 --out bags/quick_exp2 --overwrite

echo "==> forward and inverse models, 5-fold cross-validation (quick profile epochs)"
$BIN train --bag bags/quick_exp1 --model all --profile quick --out models/quick_exp1
$BIN train --bag bags/quick_exp2 --model all --profile quick --out models/quick_exp2

echo "==> mental simulation: the exp1 FM chained 10 steps on 6,000 fresh trajectories"
$BIN generate exp1 --steps 60010 --seed 99 --out bags/fresh_exp1 --overwrite
$BIN rollout --model models/quick_exp1 --bag bags/fresh_exp1

echo "==> the trainer node training an FM from the exp1 bag, then answering /trainer/predict_next_state over DDS"
tests/netns-run bash -c '
  export ROS_DOMAIN_ID="${ROS_DOMAIN_ID:-7}" RUST_LOG="${RUST_LOG:-warn}"
  RUST_LOG="${RUST_LOG},causal_arm_trainer=info" target/release/causal_arm_trainer --ros-args -p model_dir:=models/node_exp1 \
    -p "bag:=[bags/quick_exp1]" -p models:=fm -p profile:=quick -p max_folds:=1 & node=$!
  target/release/causal-arm service call /trainer/predict_next_state \
    --type causal_arm_msgs/srv/PredictNextState --timeout 120 \
    --json "{\"state\":[0,0.5,0,-1.2,0,0.8,0,0.55,0,0.45],\"action\":[0.05,0,0,0,0,0,0],\"rows\":1}"
  status=$?; kill -INT $node; wait $node; exit $status'

echo "==> causal ground truth: the simulator revisits 500 states of each bag and intervenes on every action"
$BIN intervene exp1 --bag bags/quick_exp1 --states 500 --out models/quick_exp1/truth
$BIN intervene exp2 --bag bags/quick_exp2 --states 500 --horizon 3 --out models/quick_exp2/truth

echo "==> causal discovery straight from the data (no model): the three-valued data test beside linear Granger tests, scored against that truth"
$BIN discover --bag bags/quick_exp1 --truth models/quick_exp1/truth --out models/quick_exp1/discover
$BIN discover --bag bags/quick_exp2 --truth models/quick_exp2/truth --out models/quick_exp2/discover

echo "==> knowledge extraction: Deep SHAP and Kernel SHAP with CAI; the default verdicts (drives / does not / undecided: the data test first, the model's calibrated evidence where it is undecided), scored against that truth"
$BIN explain --model models/quick_exp2 --bag bags/quick_exp2 --method deep --truth models/quick_exp2/truth
$BIN explain --model models/quick_exp2 --bag bags/quick_exp2 --method kernel --no-pair-plots --truth models/quick_exp2/truth
$BIN explain --model models/quick_exp1 --bag bags/quick_exp1 --method kernel --no-pair-plots --truth models/quick_exp1/truth

echo "==> multi-step edges: CAI through the exp2 FM chained 3 steps, scored against the truth at each horizon"
$BIN explain --model models/quick_exp2 --bag bags/quick_exp2 --method cai --horizon 3 --truth models/quick_exp2/truth

echo "==> the explainer node's latched /explainer/relevance report over DDS (state features no action affects)"
tests/netns-run bash -c '
  export ROS_DOMAIN_ID="${ROS_DOMAIN_ID:-7}" RUST_LOG="${RUST_LOG:-warn}"
  target/release/causal_arm_explainer --ros-args -p model_dir:=models/quick_exp2 -p bag:=bags/quick_exp2 & node=$!
  target/release/causal-arm topic echo /explainer/relevance --type causal_arm_msgs/msg/Relevance \
    --qos latched --count 1 --timeout 180 > models/quick_exp2/relevance_topic.json
  status=$?; kill -INT $node; wait $node
  python3 -c "import json; m = json.load(open(\"models/quick_exp2/relevance_topic.json\")); print(\"not affected by any action:\", [s for s, a in zip(m[\"state_names\"], m[\"affected\"]) if not a])"
  exit $status'

echo "==> done"
echo "    bags (rosbag2 MCAP):      bags/quick_exp1 bags/quick_exp2 bags/fresh_exp1"
echo "    models + metrics.json:    models/quick_exp1 models/quick_exp2 models/node_exp1 (trained by the node)"
echo "    mental simulation:        models/quick_exp1/mental_simulation.png"
echo "    SHAP heat map and PDPs:   models/quick_exp2/explain-deep/{heatmap,pdp_grid}.png, pdp/"
echo "    relevance report:         models/quick_exp2/explain-{deep,kernel}/relevance.{json,csv}"
echo "    causal truth + scores:    models/quick_exp{1,2}/truth/truth.{json,csv,heatmap.png}, models/quick_exp2/explain-*/scores.json"
echo "    data-level verdicts:      models/quick_exp{1,2}/discover/{claims,scores}.json"
echo "    multi-step edges:         models/quick_exp2/explain-cai-h3/multistep.json, multistep_*.png"
