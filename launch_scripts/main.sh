#!/usr/bin/env bash
# The README's main job: runs the causal-arm pipeline end to end on the embedded default
# (the iiwa URDF in urdf/). It grows with the project; today it builds the release
# binaries, shows forward and inverse kinematics of the embedded arm, and round-trips a
# /joint_states message through DDS inside a private loopback-only network namespace.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --locked --bins
BIN=target/release/causal-arm

echo "==> forward kinematics of the embedded URDF (ef frame, world frame)"
$BIN fk --joints 0,0.5,0,-1.2,0,0.8,0
echo "==> inverse kinematics to a point above the table"
$BIN ik --position 0.55,0.1,0.35 --seed 1

echo "==> /joint_states over DDS (private network namespace, loopback only)"
tests/netns-run bash -c '
  set -euo pipefail
  BIN=target/release/causal-arm
  export ROS_DOMAIN_ID=7
  $BIN topic echo /joint_states --type sensor_msgs/msg/JointState --count 1 --timeout 30 &
  echo_pid=$!
  $BIN topic pub /joint_states --type sensor_msgs/msg/JointState --wait-subscribers 1 \
    --json "{\"name\":[\"iiwa_joint_1\"],\"position\":[0.25]}" --count 1
  wait $echo_pid
'
echo "==> done"
