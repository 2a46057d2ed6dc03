#!/usr/bin/env python3
"""Soak: a paper-size exp2 run over DDS (2M steps by default), watched from outside.

Starts `causal-arm launch exp2 --profile paper` (simulator, babbler and recorder as three
DDS processes), samples every node's RSS and the recorded step count as it goes, then
checks the finished bag: every step complete (`causal-arm bag check`), the step count the
plan asks for, and no message missing against the in-process `generate` of the same seed
(per-topic counts). Prints RSS over time (it should stay flat), messages lost (0) and
steps/s, beside the in-process `generate` of the same run as the reference.

  tests/netns-run target/pyvenv/bin/python tests/bench/soak.py [--episodes N] [--bin target/release/causal-arm]

Starts DDS participants: run it inside tests/netns-run, on a quiet machine.
"""

import argparse
import json
import os
import pathlib
import re
import subprocess
import tempfile
import time

REPO = pathlib.Path(__file__).resolve().parents[2]
NODES = ("causal_arm_sim", "causal_arm_babbler", "causal_arm_recorder")


def rss_mib(pid: int) -> float:
    for line in pathlib.Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def node_pids(launcher: int) -> dict:
    path = pathlib.Path(f"/proc/{launcher}/task/{launcher}/children")
    pids = {}
    for child in map(int, path.read_text().split()):
        name = pathlib.Path(f"/proc/{child}/comm").read_text().strip()
        for node in NODES:
            if node.startswith(name):
                pids[node] = child
    return pids


def topic_counts(binary, bag) -> dict:
    out = subprocess.run([binary, "bag", "info", str(bag)], capture_output=True, text=True, check=True).stdout
    return {t["name"]: t["message_count"] for t in json.loads(out)["topics"]}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--episodes", type=int, default=None, help="override the paper profile's 4,000 episodes")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--every", type=float, default=30.0, help="seconds between RSS samples")
    ap.add_argument("--bin", default=str(REPO / "target" / "release" / "causal-arm"))
    args = ap.parse_args()
    plan = ["exp2", "--profile", "paper", "--seed", str(args.seed)]
    if args.episodes:
        plan += ["--episodes", str(args.episodes)]
    with tempfile.TemporaryDirectory(dir=REPO / "target") as tmp:
        tmp = pathlib.Path(tmp)
        start = time.monotonic()
        r = subprocess.run([args.bin, "generate", *plan, "--out", str(tmp / "local")], capture_output=True, text=True)
        assert r.returncode == 0, r.stderr[-2000:]
        local_s = time.monotonic() - start
        env = dict(os.environ, ROS_DOMAIN_ID="60", RUST_LOG="warn")
        start = time.monotonic()
        proc = subprocess.Popen([args.bin, "launch", *plan, "--out", str(tmp / "dds")], env=env,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        samples = []
        time.sleep(3)
        pids = node_pids(proc.pid)
        while proc.poll() is None:
            row = {"t": time.monotonic() - start}
            for node, pid in pids.items():
                try:
                    row[node] = rss_mib(pid)
                except FileNotFoundError:
                    row[node] = float("nan")
            samples.append(row)
            print(f"{row['t']:7.0f} s  " + "  ".join(f"{n[11:]} {row.get(n, float('nan')):6.1f} MiB" for n in NODES),
                  flush=True)
            for _ in range(int(args.every * 10)):
                if proc.poll() is not None:
                    break
                time.sleep(0.1)
        out, err = proc.communicate()
        dds_s = time.monotonic() - start
        assert proc.returncode == 0, err[-3000:]
        steps = int(re.search(r"(\d+) of (\d+) steps", out).group(1))
        check = subprocess.run([args.bin, "bag", "check", str(tmp / "dds")], capture_output=True, text=True)
        dds, ref = topic_counts(args.bin, tmp / "dds"), topic_counts(args.bin, tmp / "local")
        lost = sum(max(ref[t] - dds.get(t, 0), 0) for t in ref)
        print()
        print(f"| run | steps | wall s | steps/s | messages lost | bag check |")
        print(f"|---|---|---|---|---|---|")
        print(f"| `generate` (in process, reference) | {steps} | {local_s:.0f} | {steps / local_s:,.0f} | — | — |")
        print(f"| `launch` over DDS | {steps} | {dds_s:.0f} | {steps / dds_s:,.0f} | {lost} | "
              f"{'ok' if check.returncode == 0 else 'FAILED'} |")
        print()
        print("| node | RSS first sample MiB | RSS at half time MiB | RSS last sample MiB | max MiB |")
        print("|---|---|---|---|---|")
        for node in NODES:
            values = [s[node] for s in samples if node in s and s[node] == s[node]]
            if values:
                print(f"| {node} | {values[0]:.1f} | {values[len(values) // 2]:.1f} | {values[-1]:.1f} | {max(values):.1f} |")


if __name__ == "__main__":
    main()
