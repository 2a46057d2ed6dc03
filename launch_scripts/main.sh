#!/usr/bin/env bash
# The README's main job, end to end on the embedded default (urdf/iiwa14_magnet.urdf).
# It grows with the project; today it builds the release binaries, shows the arm's
# kinematics, then runs both experiments' data-generation graphs (simulator, babbler and
# recorder as three ROS 2 node processes over DDS, inside a private loopback-only network
# namespace) on the quick profile and writes the bags under bags/.
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
echo "==> done: bags/quick_exp1 and bags/quick_exp2 (rosbag2 MCAP; open with ros2 bag info, rosbags or mcap)"
