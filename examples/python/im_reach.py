#!/usr/bin/env python3
"""Reach effector targets with the learned inverse model, as a ROS 2 user's own node would.

The loop an rclpy user would write, here on CycloneDDS's Python binding (the middleware of
rmw_cyclonedds, so the topics, types and service mapping are the real ROS 2 ones):

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
    python examples/python/im_reach.py --target 0.4 0.2 0.9 --target -0.3 0.3 1.0 \\
        --steps-per-target 300

Each target gets --steps-per-target steps of the simulator's run, in order, the arm going
on from where the previous target left it. The report (JSON on stdout) gives, per target,
the first step within 1 cm and within 5 mm and the final distance.
"""

import argparse
import json
import math
import os
import pathlib
import random
import sys
import time
import xml.etree.ElementTree as ET

# The IDL classes of the ROS 2 types (as rosidl would generate them for Python).
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2] / "tests" / "python"))

from cyclonedds.domain import DomainParticipant  # noqa: E402
from cyclonedds.pub import DataWriter  # noqa: E402
from cyclonedds.sub import DataReader  # noqa: E402
from cyclonedds.topic import Topic  # noqa: E402

from ros_idl import (  # noqa: E402
    Action, Header, JointState, MagnetState, ObjectColor, PoseStamped, PredictActionReply,
    PredictActionRequest, RosString, ServiceClient, latched_qos, ros_default_qos,
)

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

    def __init__(self, im: ServiceClient, step: float, seed: int):
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
        reply = self.im.call(PredictActionRequest(state=q + ef, next_state=goal, rows=1))
        if not reply.success:
            raise SystemExit(f"/trainer/predict_action refused the request: {reply.message}")
        scale = min(1.0, distance / self.step)
        return [a * scale for a in reply.action[: len(q)]]

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


def wait_for_description(participant, timeout: float) -> str:
    reader = DataReader(participant, Topic(participant, "rt/robot_description", RosString), qos=latched_qos())
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        for m in reader.take(N=1):
            if isinstance(m, RosString):
                return m.data
        time.sleep(0.05)
    raise SystemExit(f"no /robot_description within {timeout} s: is the simulator running in this ROS domain?")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--target", nargs=3, type=float, action="append", required=True, metavar=("X", "Y", "Z"),
                        help="effector target in the world frame, m (repeat for several)")
    parser.add_argument("--steps-per-target", type=int, default=300)
    parser.add_argument("--step", type=float, default=0.1, help="displacement asked of the IM per step, m")
    parser.add_argument("--domain", type=int, default=None, help="ROS domain (default: ROS_DOMAIN_ID or 0)")
    parser.add_argument("--timeout", type=float, default=30.0, help="give up when the simulator is silent this long, s")
    parser.add_argument("--seed", type=int, default=0, help="seed of the babbled steps")
    args = parser.parse_args()
    if args.steps_per_target < 1 or not args.step > 0:
        parser.error("--steps-per-target and --step must be positive")

    participant = DomainParticipant(args.domain if args.domain is not None else int(os.environ.get("ROS_DOMAIN_ID", 0)))
    qos = ros_default_qos(depth=100)
    reader = lambda topic, kind: DataReader(participant, Topic(participant, topic, kind), qos=qos)  # noqa: E731
    joint_states, ef_poses = reader("rt/joint_states", JointState), reader("rt/end_effector/pose", PoseStamped)
    # The simulator waits for a reader of every state topic its babbler would read.
    others = [reader("rt/object/pose", PoseStamped), reader("rt/object/color", ObjectColor),
              reader("rt/magnet/state", MagnetState)]
    actions = DataWriter(participant, Topic(participant, "rt/babbler/action", Action), qos=qos)
    im = ServiceClient(participant, "/trainer/predict_action", PredictActionRequest, PredictActionReply)
    if not im.wait_for_server(timeout=args.timeout):
        raise SystemExit("/trainer/predict_action has no server: is the trainer node running?")
    limits = joint_limits(wait_for_description(participant, args.timeout))
    reacher = Reacher(im, args.step, args.seed)

    targets = [list(t) for t in args.target]
    report = [{"target": t, "within_1cm_at": None, "within_5mm_at": None, "final_error": None} for t in targets]
    states, poses, step = {}, {}, 0
    last_heard = time.monotonic()
    while step < len(targets) * args.steps_per_target:
        for m in joint_states.take(N=100):
            if isinstance(m, JointState):
                states[stamp_ns(m.header)] = m
        for m in ef_poses.take(N=100):
            if isinstance(m, PoseStamped):
                poses[stamp_ns(m.header)] = m
        for o in others:
            o.take(N=100)
        ready = sorted(set(states) & set(poses))
        if not ready:
            if time.monotonic() - last_heard > args.timeout:
                raise SystemExit(f"the simulator sent no state for {args.timeout} s after {step} steps")
            time.sleep(0.0005)
            continue
        last_heard = time.monotonic()
        stamp = ready[-1]
        js, pose = states.pop(stamp), poses.pop(stamp)
        states = {k: v for k, v in states.items() if k > stamp}
        poses = {k: v for k, v in poses.items() if k > stamp}
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
        actions.write(Action(header=Header(stamp=js.header.stamp), episode=0, step=step,
                             joint_deltas=[g - a for g, a in zip(goal, q)], joint_targets=goal, magnet=0))
        step += 1
    json.dump({"targets": report, "steps_per_target": args.steps_per_target, "step_m": args.step}, sys.stdout, indent=2)
    print()
    return 0


if __name__ == "__main__":
    sys.exit(main())
