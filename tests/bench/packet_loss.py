#!/usr/bin/env python3
"""The lock-step graph under random packet loss, beside two lock-step anchors, in one run.

For each loss rate (iptables `statistic --mode random` DROP on INPUT of this private
namespace's loopback; netem is not in this kernel):
  - `causal-arm launch exp1 --steps N`: steps/s while stepping, and whether the bag equals
    `causal-arm generate`'s (same seed; a run cut at --cap seconds is reported as cut);
  - anchor: CycloneDDS Python ping-pong (a JointState out, an Action back, reliable, keep
    last 100): round trips/s;
  - anchor: rclpy on rmw_fastrtps_cpp (Jazzy wheels, FASTDDS_BUILTIN_TRANSPORTS=UDPv4), the
    same ping-pong;
  - one-row `/trainer/predict_next_state` calls, one after another, from `causal-arm service
    call --count` to the trainer node: p50 / p99 / max ms.

With --baseline DIR (a directory holding another build's `causal-arm` and node binaries),
that build's launch runs right after ours at each loss rate, for a before / after.

Usage (root inside the namespace, as tests/netns-run gives):
  tests/netns-run target/pyvenv/bin/python tests/bench/packet_loss.py [--steps 3000] [--cap 120] [--runs 3] [--baseline DIR]
"""

import argparse
import datetime
import json
import os
import pathlib
import signal
import subprocess
import sys
import tempfile
import time

REPO = pathlib.Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "tests" / "python"))
sys.path.insert(0, str(REPO / "tests" / "bench"))
LOSSES = [0.0, 0.01, 0.05, 0.20]
DOMAIN = 44
ANCHOR_DEPTH = 100


def set_loss(p: float):
    """Drops each datagram this namespace receives with probability p (every process here)."""
    subprocess.run(["iptables", "-F", "INPUT"], check=True)
    if p > 0:
        subprocess.run(["iptables", "-A", "INPUT", "-m", "statistic", "--mode", "random", "--probability",
                        f"{p}", "-j", "DROP"], check=True)


def ours(binary: pathlib.Path, steps: int, cap: float, reference: pathlib.Path, tmp: pathlib.Path):
    """(steps/s while stepping, steps recorded, the bag equals generate's: True / False / None if cut)."""
    from datagen_bench import RECORDED, SIM_LOG, stepping_seconds

    out = tmp / f"bag_{time.monotonic_ns()}"
    env = {**os.environ, "ROS_DOMAIN_ID": str(DOMAIN), "RUST_LOG": "info"}
    log_path = tmp / "launch.log"
    with open(log_path, "w") as log:
        launch = subprocess.Popen([str(binary), "launch", "exp1", "--steps", str(steps), "--seed", "1",
                                   "--out", str(out)], env=env, stdout=log, stderr=subprocess.STDOUT)
        try:
            launch.wait(timeout=cap)
            cut_at = None
        except subprocess.TimeoutExpired:
            cut_at = datetime.datetime.now(datetime.timezone.utc)
            launch.send_signal(signal.SIGINT)
            launch.wait(timeout=120)
    text = log_path.read_text()
    recorded = RECORDED.findall(text)
    got = int(recorded[-1][0]) if recorded else 0
    if cut_at is None and launch.returncode == 0:
        from test_datagen import _canonical

        return steps / stepping_seconds(text), got, _canonical(out) == _canonical(reference)
    # A cut or failed launch: keep what it said, for the record.
    tail = "\n".join(text.splitlines()[-25:])
    print(f"launch {'cut' if cut_at else f'failed (exit {launch.returncode})'}; its last lines:\n{tail}",
          file=sys.stderr, flush=True)
    starts = [datetime.datetime.fromisoformat(s.replace("Z", "+00:00")) for s, w in SIM_LOG.findall(text)
              if w == "starting"]
    seconds = (cut_at - starts[0]).total_seconds() if starts and cut_at else float("nan")
    return got / seconds, got, None


def cyclone_ping_pong(role: str, seconds: float):
    """One side of the CycloneDDS anchor; the ping side prints round trips/s."""
    import ros_idl as idl
    from cyclonedds.core import ReadCondition, SampleState, ViewState, InstanceState, WaitSet
    from cyclonedds.domain import DomainParticipant
    from cyclonedds.pub import DataWriter
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic
    from cyclonedds.util import duration

    dp = DomainParticipant(DOMAIN + 1)
    qos = idl.ros_default_qos(depth=ANCHOR_DEPTH)
    state_topic = Topic(dp, "rt/anchor_state", idl.JointState)
    action_topic = Topic(dp, "rt/anchor_action", idl.Action)
    if role == "pong":
        reader, writer = DataReader(dp, state_topic, qos=qos), DataWriter(dp, action_topic, qos=qos)
    else:
        reader, writer = DataReader(dp, action_topic, qos=qos), DataWriter(dp, state_topic, qos=qos)
    waitset = WaitSet(dp)
    waitset.attach(ReadCondition(reader, SampleState.Any | ViewState.Any | InstanceState.Any))
    while not (writer.get_matched_subscriptions() and reader.get_matched_publications()):
        time.sleep(0.05)
    time.sleep(0.5)
    deadline = time.monotonic() + seconds
    rounds = 0
    if role == "ping":
        start = time.monotonic()
        writer.write(idl.JointState(name=["j"] * 7, position=[0.0] * 7))
    while time.monotonic() < deadline:
        waitset.wait(duration(milliseconds=100))
        for _ in reader.take(N=ANCHOR_DEPTH):
            rounds += 1
            if role == "pong":
                writer.write(idl.Action(step=rounds, joint_deltas=[0.0] * 7))
            else:
                writer.write(idl.JointState(name=["j"] * 7, position=[float(rounds)] * 7))
    if role == "ping":
        print(json.dumps({"rate": rounds / (time.monotonic() - start)}), flush=True)


RCLPY_PING_PONG = r"""
import json, sys, time
import rclpy
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from causal_arm_msgs.msg import Action
role, seconds = sys.argv[1], float(sys.argv[2])
rclpy.init()
node = rclpy.create_node("anchor_" + role)
qos = QoSProfile(depth=%d, reliability=ReliabilityPolicy.RELIABLE)
rounds = 0
if role == "pong":
    pub = node.create_publisher(Action, "/anchor_action", qos)
    def got(msg):
        global rounds
        rounds += 1
        pub.publish(Action(step=rounds, joint_deltas=[0.0] * 7))
    node.create_subscription(JointState, "/anchor_state", got, qos)
else:
    pub = node.create_publisher(JointState, "/anchor_state", qos)
    def got(msg):
        global rounds
        rounds += 1
        pub.publish(JointState(name=["j"] * 7, position=[float(rounds)] * 7))
    node.create_subscription(Action, "/anchor_action", got, qos)
while pub.get_subscription_count() == 0 or node.count_publishers("/anchor_action" if role == "ping" else "/anchor_state") == 0:
    rclpy.spin_once(node, timeout_sec=0.05)
time.sleep(0.5)
start = time.monotonic()
if role == "ping":
    pub.publish(JointState(name=["j"] * 7, position=[0.0] * 7))
while time.monotonic() - start < seconds:
    rclpy.spin_once(node, timeout_sec=0.1)
if role == "ping":
    print(json.dumps({"rate": rounds / (time.monotonic() - start)}), flush=True)
""" % ANCHOR_DEPTH


def anchor_rate(kind: str, seconds: float) -> float:
    """Round trips/s of one anchor's ping-pong (two processes) over `seconds`."""
    if kind == "cyclone":
        def command(role):
            return [sys.executable, __file__, "--anchor-role", role, "--anchor-seconds", str(seconds)]
        env = {**os.environ}
    else:
        script = REPO / "target" / "ros" / "jazzy" / "env.sh"
        if not script.exists():
            sys.exit(f"{script} is missing: run `bash tests/ros2/setup.sh jazzy`")

        def command(role):
            return ["bash", "-c", f'source "{script}" && exec python -c "$0" {role} {seconds + 5}', RCLPY_PING_PONG]
        env = {**os.environ, "ROS_DOMAIN_ID": str(DOMAIN + 2), "RMW_IMPLEMENTATION": "rmw_fastrtps_cpp",
               "FASTDDS_BUILTIN_TRANSPORTS": "UDPv4"}
    pong = subprocess.Popen(command("pong"), env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        ping = subprocess.run(command("ping"), env=env, capture_output=True, text=True, timeout=seconds + 120)
    finally:
        pong.kill()
        pong.wait()
    lines = [line for line in ping.stdout.splitlines() if line.startswith("{")]
    if not lines:
        raise RuntimeError(f"{kind} anchor printed nothing:\n{ping.stderr[-2000:]}")
    return json.loads(lines[-1])["rate"]


def trainer_calls(bin_dir: pathlib.Path, model_dir: pathlib.Path, calls: int):
    """(p50, p99, max) ms of one-row `/trainer/predict_next_state` calls, one after another,
    from `causal-arm service call --count` to the trainer node, both of the build in bin_dir."""
    import re

    env = dict(os.environ, ROS_DOMAIN_ID=str(DOMAIN + 3), RUST_LOG="warn")
    node = subprocess.Popen([bin_dir / "causal_arm_trainer", "--ros-args", "-p", f"model_dir:={model_dir}"],
                            env=env, stderr=subprocess.DEVNULL)
    request = json.dumps({"state": [0, 0.5, 0, -1.2, 0, 0.8, 0, 0.55, 0, 0.45],
                          "action": [0.05, 0, 0, 0, 0, 0, 0], "rows": 1})
    try:
        r = subprocess.run([bin_dir / "causal-arm", "service", "call", "/trainer/predict_next_state", "--type",
                            "causal_arm_msgs/srv/PredictNextState", "--json", request, "--count", str(calls),
                            "--timeout", "60"], env=env, capture_output=True, text=True, timeout=calls * 60 + 60)
    finally:
        node.send_signal(signal.SIGINT)
        node.wait(timeout=10)
    found = re.search(r"p50 ([\d.]+) ms, p99 ([\d.]+) ms, max ([\d.]+) ms", r.stderr)
    if r.returncode != 0 or not found:
        raise RuntimeError(f"service call failed:\n{r.stderr[-2000:]}")
    return tuple(float(x) for x in found.groups())


def summary(runs):
    """(median steps/s, fewest steps recorded, every bag equal to generate's: True / False / None
    if one was cut, "min-max" text) of several launches of one build."""
    rates = sorted(r[0] for r in runs)
    sames = [r[2] for r in runs]
    same = False if False in sames else (None if None in sames else True)
    return rates[len(rates) // 2], min(r[1] for r in runs), same, f"{rates[0]:.0f}-{rates[-1]:.0f}"


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--steps", type=int, default=3000)
    ap.add_argument("--cap", type=float, default=120.0, help="seconds after which a launch is cut (SIGINT)")
    ap.add_argument("--anchor-seconds", type=float, default=15.0)
    ap.add_argument("--calls", type=int, default=300, help="trainer calls per loss rate")
    ap.add_argument("--losses", default=",".join(str(p) for p in LOSSES))
    ap.add_argument("--bin-dir", type=pathlib.Path, default=REPO / "target" / "release")
    ap.add_argument("--baseline", type=pathlib.Path, help="another build's binaries, run beside ours")
    ap.add_argument("--runs", type=int, default=3,
                    help="launches per build and loss rate, alternating builds; the median is reported")
    ap.add_argument("--anchor-role", choices=["ping", "pong"], help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.anchor_role:
        return cyclone_ping_pong(args.anchor_role, args.anchor_seconds)
    with open("/proc/net/dev") as f:
        if [line.split(":")[0].strip() for line in f.readlines()[2:]] != ["lo"]:
            sys.exit("run inside tests/netns-run: this benchmark starts DDS participants and sets iptables rules")
    cli = args.bin_dir / "causal-arm"
    tmp = pathlib.Path(tempfile.mkdtemp(prefix="packet_loss_"))
    subprocess.run([cli, "generate", "exp1", "--steps", str(args.steps), "--seed", "1", "--out", tmp / "reference"],
                   check=True, capture_output=True)
    subprocess.run([cli, "generate", "exp1", "--profile", "quick", "--steps", "2000", "--out", tmp / "tiny"],
                   check=True, capture_output=True)
    subprocess.run([cli, "train", "--bag", tmp / "tiny", "--model", "fm", "--epochs", "1", "--folds", "2",
                    "--out", tmp / "models", "--cache", tmp / "cache"], check=True, capture_output=True)
    rows = []
    try:
        for p in [float(x) for x in args.losses.split(",")]:
            set_loss(p)
            mine, theirs = [], []
            for run in range(args.runs):
                print(f"loss {p:.0%}: launch {run + 1}/{args.runs}", flush=True)
                mine.append(ours(cli, args.steps, args.cap, tmp / "reference", tmp))
                if args.baseline:
                    print(f"loss {p:.0%}: launch {run + 1}/{args.runs} of the baseline", flush=True)
                    theirs.append(ours(args.baseline / "causal-arm", args.steps, args.cap, tmp / "reference", tmp))
            rate, got, same, spread = summary(mine)
            before = summary(theirs) if args.baseline else None
            print(f"loss {p:.0%}: anchors", flush=True)
            cyclone = anchor_rate("cyclone", args.anchor_seconds)
            rclpy = anchor_rate("rclpy", args.anchor_seconds)
            print(f"loss {p:.0%}: trainer calls", flush=True)
            calls = [trainer_calls(args.bin_dir, tmp / "models", args.calls)]
            if args.baseline:
                calls.append(trainer_calls(args.baseline, tmp / "models", args.calls))
            rows.append((p, (rate, got, same, spread), cyclone, rclpy, calls, before))
    finally:
        set_loss(0)
    print(f"\nlaunch exp1 --steps {args.steps} (cut at {args.cap:.0f} s), median of {args.runs} launches "
          f"(min-max); anchors: lock-step ping-pong, reliable, keep last {ANCHOR_DEPTH}, "
          f"{args.anchor_seconds:.0f} s each")
    print(f"{'loss':>5} {'ours steps/s':>13} {'min-max':>13} {'of 0 %':>7} {'steps':>6} {'bag = generate':>15} "
          f"{'CycloneDDS':>11} {'of 0 %':>7} {'rclpy/Fast DDS':>15} {'of 0 %':>7}")
    base = rows[0]
    verdicts = {True: "yes", False: "NO", None: "cut"}
    for p, (rate, got, same, spread), cyclone, rclpy, _, _ in rows:
        print(f"{p:>5.0%} {rate:>13.1f} {spread:>13} {rate / base[1][0]:>7.1%} {got:>6} {verdicts[same]:>15} "
              f"{cyclone:>11.1f} {cyclone / base[2]:>7.1%} {rclpy:>15.1f} {rclpy / base[3]:>7.1%}")
    if args.baseline:
        print(f"\nbaseline build ({args.baseline}), same runs")
        print(f"{'loss':>5} {'steps/s':>13} {'min-max':>13} {'of 0 %':>7} {'steps':>6} {'bag = generate':>15}")
        first = base[5][0]
        for p, *_, (rate, got, same, spread) in rows:
            print(f"{p:>5.0%} {rate:>13.1f} {spread:>13} {rate / first:>7.1%} {got:>6} {verdicts[same]:>15}")
    print(f"\none-row /trainer/predict_next_state: `causal-arm service call --count {args.calls}` to the "
          "trainer node, round trips (ms)")
    print(f"{'loss':>5} {'p50':>9} {'p99':>9} {'max':>9}" + (f" {'base p50':>9} {'base p99':>9} {'base max':>9}"
                                                          if args.baseline else ""))
    for p, *_, calls, _ in rows:
        print(f"{p:>5.0%}" + "".join(f" {p50:>9.3f} {p99:>9.3f} {mx:>9.3f}" for p50, p99, mx in calls))


if __name__ == "__main__":
    main()
