#!/usr/bin/env python3
"""Data-generation speed: ours vs PyBullet on the same babbling loop, side by side.

Runs, in one go on this machine:
  * `causal-arm generate exp1` (simulator + babbler + bag writing, one process, no DDS)
  * `causal-arm generate exp2`
  * both again with `--arm dynamic` (the arm a multibody under gravity moved by
    speed- and torque-limited motors, instead of kinematic bodies placed by forward
    kinematics)
  * both again with `--shards 2` (two seeded shards simulated side by side, one per core),
    and `launch exp1 --shards 2` (two graphs in two ROS domains)
  * `causal-arm launch exp1` (simulator, babbler and recorder as three DDS processes in
    lock-step; only when run inside tests/netns-run, since it starts DDS participants)
  * `causal-arm launch exp1 --composed` (the same three nodes composed in one process,
    as an rclcpp component container: they hand each other messages in process and still
    publish every topic on DDS), alone and with `--shards 2`
  * a PyBullet script doing the paper's exp1 loop: pybullet_data's kuka_iiwa, random
    normal joint targets (sigma 0.35, clipped to the limits), POSITION_CONTROL with the
    URDF forces, 10 substeps at 240 Hz, reading joint states and the end-effector pose
    each step (no recording, so it is a lower bound on PyBullet's cost).
Prints a table with steps/s and ratios to the PyBullet loop (run first and last, as this VM's
speed drifts; the reference is the mean of the two; every run timed whole, start-up
included), then the
DDS graphs again while stepping only (from the simulators' "starting" and "done" log lines:
the PyBullet loop is timed without connecting and loading its URDF) with the steps requested
but missing from the bag. Usage:
  tests/netns-run target/pyvenv/bin/python tests/bench/datagen_bench.py [--steps N] [--bin target/release/causal-arm]
Run it on a quiet machine (nothing else building).
"""

import argparse
import pathlib
import re
import subprocess
import tempfile
import time

import numpy as np
import pybullet as p
import pybullet_data

REPO = pathlib.Path(__file__).resolve().parents[2]
LIMITS = np.array([2.967, 2.094, 2.967, 2.094, 2.967, 2.094, 3.054])


def pybullet_exp1(steps: int, seed: int = 0) -> float:
    client = p.connect(p.DIRECT)
    p.setAdditionalSearchPath(pybullet_data.getDataPath(), physicsClientId=client)
    p.setGravity(0, 0, -9.81, physicsClientId=client)
    p.setTimeStep(1.0 / 240.0, physicsClientId=client)
    robot = p.loadURDF("kuka_iiwa/model.urdf", useFixedBase=True, physicsClientId=client)
    joints = list(range(7))
    forces = [p.getJointInfo(robot, j, physicsClientId=client)[10] or 300.0 for j in joints]
    rng = np.random.default_rng(seed)
    start = time.perf_counter()
    for _ in range(steps):
        target = np.clip(rng.normal(0.0, 0.35, 7), -LIMITS, LIMITS)
        p.setJointMotorControlArray(robot, joints, p.POSITION_CONTROL, targetPositions=target.tolist(),
                                    forces=forces, physicsClientId=client)
        for _ in range(10):
            p.stepSimulation(physicsClientId=client)
        p.getJointStates(robot, joints, physicsClientId=client)
        p.getLinkState(robot, 6, computeForwardKinematics=True, physicsClientId=client)
    elapsed = time.perf_counter() - start
    p.disconnect(client)
    return steps / elapsed


def in_private_netns() -> bool:
    with open("/proc/net/dev") as f:
        return [line.split(":")[0].strip() for line in f.readlines()[2:]] == ["lo"]


SIM_LOG = re.compile(r"^(\S+Z)\s+INFO simulator (starting|done)", re.M)
RECORDED = re.compile(r"\((\d+) of (\d+) steps (?:over DDS|by nodes composed)")


def stepping_seconds(log: str) -> float:
    """Wall time from the first simulator's first step to the last one's end (each logs
    "simulator starting" once its readers matched, and "simulator done" once the recorder
    acknowledged its last step): the launch without process start-up and discovery, as the
    PyBullet loop is timed without connecting and loading the URDF."""
    import datetime

    stamps = {"starting": [], "done": []}
    for stamp, what in SIM_LOG.findall(log):
        stamps[what].append(datetime.datetime.fromisoformat(stamp.replace("Z", "+00:00")))
    if not stamps["starting"] or len(stamps["done"]) != len(stamps["starting"]):
        raise RuntimeError(f"simulator start/done lines missing from the launch log:\n{log[-2000:]}")
    return (max(stamps["done"]) - min(stamps["starting"])).total_seconds()


def ours_dds(binary: str, steps: int, shards: int = 1, composed: bool = False) -> tuple[float, float, int]:
    """(steps/s over the whole `launch`, start-up and discovery included (~1 s); steps/s
    while stepping; steps requested but not in the bag). `composed`: the three nodes in one
    process, handing each other their messages in process (`launch --composed`)."""
    import os

    with tempfile.TemporaryDirectory() as tmp:
        out = pathlib.Path(tmp) / "bag"
        env = {**os.environ, "ROS_DOMAIN_ID": "42", "RUST_LOG": "info"}
        start = time.perf_counter()
        command = [binary, "launch", "exp1", "--steps", str(steps), "--seed", "1", "--shards", str(shards),
                   "--out", str(out)] + ["--composed"] * composed
        run = subprocess.run(command, check=True, capture_output=True, text=True, env=env)
        whole = time.perf_counter() - start
        log = run.stdout + run.stderr
        recorded = RECORDED.findall(log)
        if len(recorded) != shards:
            raise RuntimeError(f"expected {shards} bag lines, got {recorded}")
        lost = sum(int(total) - int(got) for got, total in recorded)
        return steps / whole, steps / stepping_seconds(log), lost


def ours(binary: str, experiment: str, steps: int, shards: int = 1, arm: str = "kinematic") -> float:
    with tempfile.TemporaryDirectory() as tmp:
        out = pathlib.Path(tmp) / "bag"
        size = ["--steps", str(steps)] if experiment == "exp1" else ["--episodes", str(max(1, steps // 500))]
        total = steps if experiment == "exp1" else max(1, steps // 500) * 500
        start = time.perf_counter()
        subprocess.run([binary, "generate", experiment, *size, "--seed", "1", "--shards", str(shards),
                        "--arm", arm, "--out", str(out)], check=True, capture_output=True, text=True)
        elapsed = time.perf_counter() - start
        return total / elapsed


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--steps", type=int, default=20000)
    parser.add_argument("--bin", default=str(REPO / "target" / "release" / "causal-arm"))
    args = parser.parse_args()
    rows = [
        ("PyBullet exp1 loop (reference, no recording)", pybullet_exp1(args.steps)),  # run again at the end
        ("causal-arm generate exp1 (in-process, writes bag)", ours(args.bin, "exp1", args.steps)),
        ("causal-arm generate exp2 (in-process, writes bag)", ours(args.bin, "exp2", args.steps)),
        ("causal-arm generate exp1 --arm dynamic", ours(args.bin, "exp1", args.steps, arm="dynamic")),
        ("causal-arm generate exp2 --arm dynamic", ours(args.bin, "exp2", args.steps, arm="dynamic")),
        ("causal-arm generate exp1 --shards 2 (2 threads)", ours(args.bin, "exp1", args.steps, 2)),
        ("causal-arm generate exp2 --shards 2 (2 threads)", ours(args.bin, "exp2", args.steps, 2)),
    ]
    graphs = []
    if in_private_netns():
        graphs.append(("causal-arm launch exp1 (3 DDS processes, lock-step)", ours_dds(args.bin, args.steps)))
        graphs.append(("causal-arm launch exp1 --shards 2 (2 graphs)", ours_dds(args.bin, args.steps, 2)))
        graphs.append(("causal-arm launch exp1 --composed (3 nodes, 1 process)",
                       ours_dds(args.bin, args.steps, composed=True)))
        graphs.append(("causal-arm launch exp1 --composed --shards 2",
                       ours_dds(args.bin, args.steps, 2, composed=True)))
    else:
        print("not inside tests/netns-run: skipping the DDS graph rows")
    rows += [(name, whole) for name, (whole, _, _) in graphs]
    # This VM's speed drifts within minutes: the reference is the mean of a PyBullet run
    # before everything else and one after.
    first, last = rows[0][1], pybullet_exp1(args.steps)
    print(f"PyBullet exp1 loop: {first:.0f} steps/s first, {last:.0f} last; the reference is their mean")
    rows[0] = (rows[0][0], (first + last) / 2)
    ref = rows[0][1]
    print(f"\n{'run':<56} {'steps/s':>10} {'vs PyBullet':>12}")
    for name, rate in rows:
        print(f"{name:<56} {rate:>10.0f} {rate / ref:>11.2f}x")
    if graphs:
        print("\nThe DDS graphs while stepping (start-up and discovery left out, as the PyBullet loop's are):")
        print(f"{'run':<56} {'steps/s':>10} {'vs PyBullet':>12} {'steps lost':>11}")
        for name, (_, stepping, lost) in graphs:
            print(f"{name:<56} {stepping:>10.0f} {stepping / ref:>11.2f}x {lost:>11}")
    by_name = dict(rows)
    for experiment in ["exp1", "exp2"]:
        one = by_name[f"causal-arm generate {experiment} (in-process, writes bag)"]
        two = by_name[f"causal-arm generate {experiment} --shards 2 (2 threads)"]
        print(f"{experiment}: 2 shards are {two / one:.2f}x one shard")
        dynamic = by_name[f"causal-arm generate {experiment} --arm dynamic"]
        print(f"{experiment}: the dynamic arm runs at {dynamic / one:.2f}x the kinematic one")
    if "causal-arm launch exp1 --shards 2 (2 graphs)" in by_name:
        one = by_name["causal-arm launch exp1 (3 DDS processes, lock-step)"]
        two = by_name["causal-arm launch exp1 --shards 2 (2 graphs)"]
        print(f"launch exp1: 2 graphs are {two / one:.2f}x one graph")


if __name__ == "__main__":
    main()
