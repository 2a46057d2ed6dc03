#!/usr/bin/env python3
"""Latency of `/trainer/predict_next_state` seen by a ROS 2 client, beside the DDS floor.

Runs, in one go: a tiny exp1 dataset and FM (so the script is self-contained unless
--model-dir is given), the `causal_arm_trainer` node, and a CycloneDDS Python client that
calls the service N times with 1 row and with 256 rows. As the reference it measures the
same client against a CycloneDDS Python server that answers immediately without a model:
the round-trip floor of the two DDS stacks. Prints p50 / p99 / max in ms.

Usage (DDS must stay on loopback):
  tests/netns-run target/pyvenv/bin/python tests/bench/service_latency.py [--calls 2000] [--model-dir DIR]
Target (issue 5): p99 < 2 ms for one row. Run on a quiet machine.
"""

import argparse
import os
import pathlib
import signal
import subprocess
import sys
import tempfile
import threading
import time

import numpy as np

REPO = pathlib.Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "tests" / "python"))
import ros_idl as idl  # noqa: E402


def percentiles(samples):
    a = np.array(samples) * 1e3
    return np.percentile(a, 50), np.percentile(a, 99), a.max()


def measure(client, request, calls):
    for _ in range(50):
        client.call(request)
    times = []
    for _ in range(calls):
        start = time.perf_counter()
        reply = client.call(request)
        times.append(time.perf_counter() - start)
        assert reply.success, reply.message
    return percentiles(times)


def echo_server(participant, stop):
    """Answers predict_next_state requests at once with an empty success reply."""
    from cyclonedds.pub import DataWriter
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic

    qos = idl.ros_default_qos(depth=100)
    reader = DataReader(participant, Topic(participant, "rq/echo/predict_next_stateRequest", idl.PredictNextStateRequest), qos=qos)
    writer = DataWriter(participant, Topic(participant, "rr/echo/predict_next_stateReply", idl.PredictNextStateReply), qos=qos)
    while not stop.is_set():
        for req in reader.take(N=16):
            writer.write(idl.PredictNextStateReply(client_guid=req.client_guid, sequence_number=req.sequence_number,
                                                   success=True, rows=req.rows))
        time.sleep(0.0001)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--calls", type=int, default=2000)
    ap.add_argument("--model-dir", type=pathlib.Path)
    ap.add_argument("--bin-dir", type=pathlib.Path, default=REPO / "target" / "release")
    args = ap.parse_args()
    with open("/proc/net/dev") as f:
        if [line.split(":")[0].strip() for line in f.readlines()[2:]] != ["lo"]:
            sys.exit("run inside tests/netns-run: this benchmark starts DDS participants")
    cli = args.bin_dir / "causal-arm"
    tmp = pathlib.Path(tempfile.mkdtemp())
    model_dir = args.model_dir
    if model_dir is None:
        model_dir = tmp / "models"
        subprocess.run([cli, "generate", "exp1", "--profile", "quick", "--steps", "2000", "--out", tmp / "bag"], check=True, capture_output=True)
        subprocess.run([cli, "train", "--bag", tmp / "bag", "--model", "fm", "--epochs", "1", "--folds", "2", "--out", model_dir,
                        "--cache", tmp / "cache"], check=True, capture_output=True)
    env = dict(os.environ, RMW_IMPLEMENTATION="rmw_cyclonedds_cpp", ROS_DOMAIN_ID="43")
    node = subprocess.Popen([args.bin_dir / "causal_arm_trainer", "--ros-args", "-p", f"model_dir:={model_dir}"], env=env,
                            stderr=subprocess.DEVNULL)
    from cyclonedds.domain import DomainParticipant

    participant = DomainParticipant(43)
    stop = threading.Event()
    server = threading.Thread(target=echo_server, args=(DomainParticipant(43), stop), daemon=True)
    server.start()
    try:
        ours = idl.ServiceClient(participant, "/trainer/predict_next_state", idl.PredictNextStateRequest, idl.PredictNextStateReply)
        echo = idl.ServiceClient(participant, "/echo/predict_next_state", idl.PredictNextStateRequest, idl.PredictNextStateReply)
        assert ours.wait_for_server(), "causal_arm_trainer did not match"
        assert echo.wait_for_server(), "echo server did not match"
        rng = np.random.default_rng(0)
        rows = []
        for n in (1, 256):
            req = idl.PredictNextStateRequest(state=rng.normal(0, 0.3, n * 10).tolist(), action=rng.normal(0, 0.05, n * 7).tolist(), rows=n)
            rows.append((f"causal_arm_trainer, {n} row(s)", measure(ours, req, args.calls)))
            rows.append((f"reference: Python echo server, {n} row(s)", measure(echo, req, args.calls)))
    finally:
        stop.set()
        node.send_signal(signal.SIGINT)
        node.wait(timeout=10)
    print(f"\n{'service call (' + str(args.calls) + ' calls)':<44} {'p50 ms':>8} {'p99 ms':>8} {'max ms':>8}")
    for label, (p50, p99, mx) in rows:
        print(f"{label:<44} {p50:8.3f} {p99:8.3f} {mx:8.3f}")


if __name__ == "__main__":
    main()
