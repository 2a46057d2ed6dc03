#!/usr/bin/env python3
"""What an rclpy node that is already running sees of a `causal-arm launch`, beside an rclpy
publisher started the same way in the same run (the reference: rmw_fastrtps_cpp to itself).

For each ROS 2 distribution, a watcher rclpy node subscribes to /joint_states and /talk; then,
alternately, `causal-arm launch exp1` runs, and a second rclpy node starts and publishes on
/talk. Per run: whether the watcher got the launch's first step and every step, when its first
sample arrived and when it knew all three node names (from the process start), and for the
reference when its first sample arrived (from the process start and from its node's creation)
and when its node name was known. Times are CLOCK_MONOTONIC, shared by all processes.

Usage (starts DDS participants: inside tests/netns-run, on a quiet machine; needs
tests/ros2/setup.sh DISTRO done):
  tests/netns-run target/pyvenv/bin/python tests/bench/rclpy_discovery.py [--runs 20] [--steps 1000]
"""

import argparse
import os
import pathlib
import statistics
import subprocess
import sys
import threading
import time

ROOT = pathlib.Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests" / "python"))
from rclpy_peer import RclpyPeer  # noqa: E402

OUR_NODES = {"/causal_arm_sim", "/causal_arm_babbler", "/causal_arm_recorder"}


def env(domain):
    # UDP only, as our nodes speak: Fast DDS between its own processes would use shared
    # memory, and a talker restarted on the port of the previous one got nothing in 1 of 4.
    return {**os.environ, "ROS_DOMAIN_ID": str(domain), "RMW_IMPLEMENTATION": "rmw_fastrtps_cpp",
            "FASTDDS_BUILTIN_TRANSPORTS": "UDPv4", "RUST_LOG": "warn"}


def names_known_at(watcher, names, done, every=0.01):
    """First time the watcher's graph holds all `names`, polling until `done()`."""
    while not done():
        if names <= set(watcher.graph()["nodes"]):
            return time.monotonic()
        time.sleep(every)
    return None


GONE_WAIT = 25.0


def gone_after(watcher, names, max_wait=GONE_WAIT):
    """Seconds until none of `names` is in the watcher's graph (nodes of the previous run
    that left without saying so stay until their lease expires)."""
    start = time.monotonic()
    while names & set(watcher.graph()["nodes"]):
        if time.monotonic() - start > max_wait:
            break
        time.sleep(0.01)
    return time.monotonic() - start


def our_launch(watcher, binary, steps, out, domain):
    left = gone_after(watcher, OUR_NODES)
    start = time.monotonic()
    launch = subprocess.Popen([binary, "launch", "exp1", "--steps", str(steps), "--seed", "3", "--out", out,
                               "--overwrite"], env=env(domain), stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL)
    named = names_known_at(watcher, OUR_NODES, lambda: launch.poll() is not None)
    launch.wait()
    samples = watcher.take(topic="/joint_states", count=steps, timeout=3)
    stamps = [s["msg"]["header"]["stamp"] for s in samples]
    first = samples[0]["t"] - start if samples else None
    return {
        "step0": bool(stamps) and stamps[0] == {"sec": 0, "nanosec": 0},
        "got": len(samples),
        "first": first,
        # Names still there from the previous run say nothing about this one.
        "names": named - start if named and left < GONE_WAIT else None,
        "previous_left": left,
    }


def rclpy_reference(watcher, distro, domain):
    left = gone_after(watcher, {"/rclpy_talker"})
    start = time.monotonic()
    with RclpyPeer(distro, "rclpy_talker", env(domain)) as talker:
        talking = threading.Thread(target=lambda: talker.publish(
            topic="/talk", type="std_msgs/msg/String", messages=[{"data": str(i)} for i in range(100)],
            period=0.01))
        talking.start()
        named = names_known_at(watcher, {"/rclpy_talker"}, lambda: not talking.is_alive())
        talking.join()
        created = talker.info["created"]
    samples = watcher.take(topic="/talk", count=100, timeout=3)
    first = samples[0]["t"] if samples else None
    return {
        "first": first - start if first else None,
        "first_after_node": first - created if first else None,
        "names": named - start if named and left < GONE_WAIT else None,
        "got": len(samples),
        "previous_left": left,
    }


def fmt(x):
    return "   -  " if x is None else f"{x:6.3f}"


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--distros", default="jazzy,kilted")
    parser.add_argument("--runs", type=int, default=20)
    parser.add_argument("--steps", type=int, default=1000)
    parser.add_argument("--bin", default=str(ROOT / "target" / "debug" / "causal-arm"))
    parser.add_argument("--domain", type=int, default=57)
    args = parser.parse_args()
    out = "/tmp/rclpy_discovery_bag"
    summary = []
    for distro in args.distros.split(","):
        with RclpyPeer(distro, "rclpy_watcher", env(args.domain)) as watcher:
            watcher.subscribe(topic="/joint_states", type="sensor_msgs/msg/JointState", qos={"depth": 100000})
            watcher.subscribe(topic="/talk", type="std_msgs/msg/String", qos={"depth": 1000})
            print(f"\n{distro}: launch exp1 --steps {args.steps} (ours) | rclpy talker (reference), s from process start")
            print(" run | step 0  got    first  names  names-first  prev-left | first  first-after-node  names  prev-left")
            ours, refs = [], []
            for run in range(args.runs):
                # Interleaved: the VM's speed drifts.
                a = our_launch(watcher, args.bin, args.steps, out, args.domain)
                b = rclpy_reference(watcher, distro, args.domain)
                ours.append(a)
                refs.append(b)
                gap = a["names"] - a["first"] if a["names"] is not None and a["first"] is not None else None
                print(f" {run + 1:3d} | {'yes' if a['step0'] else 'NO ':>6} {a['got']:5d} {fmt(a['first'])} {fmt(a['names'])} "
                      f"{fmt(gap)}       {fmt(a['previous_left'])} | {fmt(b['first'])} {fmt(b['first_after_node'])}           "
                      f"{fmt(b['names'])} {fmt(b['previous_left'])}",
                      flush=True)
            summary.append((distro, ours, refs))
    print("\nsummary (median / max, s)")
    for distro, ours, refs in summary:
        med = lambda xs: statistics.median(xs) if xs else float("nan")
        firsts = [a["first"] for a in ours if a["first"] is not None]
        gaps = [a["names"] - a["first"] for a in ours if a["names"] is not None and a["first"] is not None]
        rfirst = [b["first"] for b in refs if b["first"] is not None]
        rnode = [b["first_after_node"] for b in refs if b["first_after_node"] is not None]
        print(f"{distro}: ours: first step received in {sum(a['step0'] for a in ours)} of {len(ours)} runs, "
              f"every step in {sum(a['got'] == args.steps for a in ours)}; first sample {med(firsts):.3f} / "
              f"{max(firsts, default=float('nan')):.3f}; names after first sample {med(gaps):.3f} / "
              f"{max(gaps, default=float('nan')):.3f} | rclpy: first sample {med(rfirst):.3f} from start, "
              f"{med(rnode):.3f} from its node's creation")


if __name__ == "__main__":
    main()
