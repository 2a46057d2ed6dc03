#!/usr/bin/env python3
"""Reach effector targets with the learned inverse model, as a ROS 2 user's own node would.

An rclpy node with the colcon-built `causal_arm_msgs` (README, "From rclpy"); under either
rmw, as long as the trainer speaks the same service mapping (RMW_IMPLEMENTATION). Its loop:

1. take the simulator's state of this step: /joint_states and /end_effector/pose;
2. ask /trainer/predict_action for the action that moves the effector a full --step
   toward the target (θ(t), ef(t), ef*), and scale it down to the remaining distance once
   closer than that; after 20 steps without 1 mm of progress, babble one step instead;
3. answer the simulator on /babbler/action with the joint targets, within the limits of
   the arm's /robot_description.

Start the simulator (lock-stepped with whoever answers it) and the trainer first, in one
ROS domain; the simulator must take actions from a node that is not its graph's babbler:

    causal_arm_sim --ros-args -p experiment:=exp1 -p steps:=600 \\
        -p wait_for_recorder:=false -p trusted_publishers:='*'
    causal_arm_trainer --ros-args -p model_dir:=models/exp1   # from `causal-arm train`
    #   (a directory holding only an IM: add -p forward_model:=im-mono, as this loop never
    #   asks the forward model)
    python3 examples/python/im_reach.py --target 0.4 0.2 0.9 --target -0.3 0.3 1.0 \\
        --steps-per-target 300

Each target gets --steps-per-target steps of the simulator's run, in order, the arm going
on from where the previous target left it. The report (JSON on stdout) gives, per target,
the first step within 1 cm and within 5 mm and the final distance.
"""

import argparse
import json
import math
import random
import sys
import time
import xml.etree.ElementTree as ET

import rclpy
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from causal_arm_msgs.msg import Action, MagnetState, ObjectColor
from causal_arm_msgs.srv import PredictAction
from geometry_msgs.msg import PoseStamped
from sensor_msgs.msg import JointState
from std_msgs.msg import String

JOINTS = [f"iiwa_joint_{i}" for i in range(1, 8)]
STALL_STEPS = 20


def stamp_ns(header) -> int:
    return header.stamp.sec * 1_000_000_000 + header.stamp.nanosec


def joint_limits(urdf: str) -> list:
    """(lower, upper) of each arm joint, from the URDF the simulator publishes."""
    joints = {j.get("name"): j.find("limit") for j in ET.fromstring(urdf).iter("joint")}
    missing = [n for n in JOINTS if joints.get(n) is None]
    if missing:
        raise SystemExit(f"/robot_description has no limits for {missing}")
    return [(float(joints[n].get("lower")), float(joints[n].get("upper"))) for n in JOINTS]


class Reacher:
    """The controller: what to command for one state, given the IM service."""

    def __init__(self, im, step: float, seed: int):
        self.im, self.step = im, step
        self.rng = random.Random(seed)
        self.target, self.best, self.since_best = None, math.inf, 0

    def joint_deltas(self, q: list, ef: list, target: list) -> list:
        offset = [t - e for t, e in zip(target, ef)]
        distance = math.sqrt(sum(d * d for d in offset))
        if self.stalled(target, distance):
            return [self.rng.gauss(0.0, 0.3) for _ in q]
        if distance == 0.0:
            return [0.0] * len(q)
        goal = [e + d * self.step / distance for e, d in zip(ef, offset)]
        reply = self.im(PredictAction.Request(state=q + ef, next_state=goal, rows=1))
        if not reply.success:
            raise SystemExit(f"/trainer/predict_action refused the request: {reply.message}")
        scale = min(1.0, distance / self.step)
        return [float(a) * scale for a in reply.action[: len(q)]]

    def stalled(self, target: list, distance: float) -> bool:
        if target != self.target:
            self.target, self.best, self.since_best = target, distance, 0
        elif distance < self.best - 1e-3:
            self.best, self.since_best = distance, 0
        else:
            self.since_best += 1
        if self.since_best < STALL_STEPS:
            return False
        self.best, self.since_best = distance, 0
        return True


class Node:
    """The node's DDS side: state in, actions out, the IM service, the arm's description."""

    def __init__(self, timeout: float):
        self.node = rclpy.create_node("im_reach")
        self.timeout = timeout
        reliable = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
        self.states, self.poses, self.description = {}, {}, None
        self.node.create_subscription(JointState, "/joint_states", self.keep(self.states), reliable)
        self.node.create_subscription(PoseStamped, "/end_effector/pose", self.keep(self.poses), reliable)
        # The simulator waits for a reader of every state topic its babbler would read.
        for kind, topic in [(PoseStamped, "/object/pose"), (ObjectColor, "/object/color"),
                            (MagnetState, "/magnet/state")]:
            self.node.create_subscription(kind, topic, lambda _: None, reliable)
        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.node.create_subscription(String, "/robot_description", self.described, latched)
        self.actions = self.node.create_publisher(Action, "/babbler/action", reliable)
        self.im = self.node.create_client(PredictAction, "/trainer/predict_action")

    @staticmethod
    def keep(into: dict):
        return lambda m: into.__setitem__(stamp_ns(m.header), m)

    def described(self, message):
        self.description = message.data

    def wait_for_the_graph(self) -> str:
        if not self.im.wait_for_service(timeout_sec=self.timeout):
            raise SystemExit("/trainer/predict_action has no server: is the trainer node running?")
        deadline = time.monotonic() + self.timeout
        while self.description is None:
            if time.monotonic() > deadline:
                raise SystemExit(f"no /robot_description within {self.timeout} s: "
                                 "is the simulator running in this ROS domain?")
            rclpy.spin_once(self.node, timeout_sec=0.05)
        return self.description

    def predict_action(self, request):
        future = self.im.call_async(request)
        rclpy.spin_until_future_complete(self.node, future, timeout_sec=self.timeout)
        if not future.done():
            raise SystemExit(f"/trainer/predict_action did not answer within {self.timeout} s")
        return future.result()

    def next_state(self):
        """The newest step with both its joint state and its effector pose; older ones go."""
        deadline = time.monotonic() + self.timeout
        while not (ready := sorted(set(self.states) & set(self.poses))):
            if time.monotonic() > deadline:
                raise SystemExit(f"the simulator sent no state for {self.timeout} s")
            rclpy.spin_once(self.node, timeout_sec=0.01)
        stamp = ready[-1]
        js, pose = self.states.pop(stamp), self.poses.pop(stamp)
        for kept in (self.states, self.poses):
            for old in [k for k in kept if k <= stamp]:
                del kept[old]
        return js, pose


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--target", nargs=3, type=float, action="append", required=True, metavar=("X", "Y", "Z"),
                        help="effector target in the world frame, m (repeat for several)")
    parser.add_argument("--steps-per-target", type=int, default=300)
    parser.add_argument("--step", type=float, default=0.1, help="displacement asked of the IM per step, m")
    parser.add_argument("--timeout", type=float, default=30.0, help="give up when the simulator is silent this long, s")
    parser.add_argument("--seed", type=int, default=0, help="seed of the babbled steps")
    args, ros_args = parser.parse_known_args()
    if args.steps_per_target < 1 or not args.step > 0:
        parser.error("--steps-per-target and --step must be positive")

    rclpy.init(args=[sys.argv[0], *ros_args])
    try:
        report = reach(Node(args.timeout), args)
    finally:
        rclpy.try_shutdown()
    json.dump({"targets": report, "steps_per_target": args.steps_per_target, "step_m": args.step}, sys.stdout, indent=2)
    print()
    return 0


def reach(node: Node, args) -> list:
    limits = joint_limits(node.wait_for_the_graph())
    reacher = Reacher(node.predict_action, args.step, args.seed)
    targets = [list(t) for t in args.target]
    report = [{"target": t, "within_1cm_at": None, "within_5mm_at": None, "final_error": None} for t in targets]
    for step in range(len(targets) * args.steps_per_target):
        js, pose = node.next_state()
        q = [js.position[js.name.index(n)] for n in JOINTS]
        p = pose.pose.position
        ef = [p.x, p.y, p.z]
        index = step // args.steps_per_target
        entry, k = report[index], step % args.steps_per_target
        error = math.dist(ef, targets[index])
        if k > 0 or index == 0:
            entry["final_error"] = error
            if error <= 0.01 and entry["within_1cm_at"] is None:
                entry["within_1cm_at"] = k
            if error <= 0.005 and entry["within_5mm_at"] is None:
                entry["within_5mm_at"] = k
        deltas = [0.0] * 7 if entry["within_5mm_at"] is not None else reacher.joint_deltas(q, ef, targets[index])
        goal = [min(max(a + d, lo), hi) for a, d, (lo, hi) in zip(q, deltas, limits)]
        action = Action(episode=0, step=step, joint_deltas=[g - a for g, a in zip(goal, q)], joint_targets=goal,
                        magnet=0)
        action.header.stamp = js.header.stamp
        node.actions.publish(action)
    return report


if __name__ == "__main__":
    sys.exit(main())
