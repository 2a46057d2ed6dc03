#!/usr/bin/env python3
"""Where a step of the DDS graph goes: syscalls, context switches and CPU per thread.

Runs `causal-arm launch exp1` twice (it starts DDS participants: run it inside
tests/netns-run, on a quiet machine):
  1. under `perf stat` with syscall tracepoints: sendto, recvfrom, recvmsg, epoll_wait,
     futex, write per step, context switches per step, CPU time per step;
  2. alone, sampling each node thread's CPU time (/proc/PID/task/TID/stat) over a window
     in the middle of the run: each thread's share of a core and its µs per step.
The first is skipped, with a note, where perf or its tracepoints are not available.
Usage:
  tests/netns-run target/pyvenv/bin/python tests/bench/dds_step_cost.py [--steps N] [--bin PATH]
"""

import argparse
import os
import pathlib
import re
import shutil
import subprocess
import tempfile
import time

REPO = pathlib.Path(__file__).resolve().parents[2]
SYSCALLS = ["sendto", "recvfrom", "recvmsg", "epoll_wait", "futex", "write"]
NODES = ("causal_arm_sim", "causal_arm_babb", "causal_arm_reco")


def launch_command(binary: str, steps: int, out: pathlib.Path) -> list[str]:
    return [binary, "launch", "exp1", "--steps", str(steps), "--seed", "1", "--out", str(out)]


def env() -> dict:
    return {**os.environ, "ROS_DOMAIN_ID": "43", "RUST_LOG": "error"}


def syscalls_per_step(binary: str, steps: int) -> list[tuple[str, float]] | None:
    if shutil.which("perf") is None:
        print("perf not found: no syscall counts")
        return None
    events = [f"syscalls:sys_enter_{s}" for s in SYSCALLS] + ["context-switches", "task-clock"]
    with tempfile.TemporaryDirectory() as tmp:
        run = subprocess.run(["perf", "stat", "-x", ",", *sum((["-e", e] for e in events), []),
                              *launch_command(binary, steps, pathlib.Path(tmp) / "bag")],
                             capture_output=True, text=True, env=env())
    if run.returncode != 0:
        print(f"perf stat failed ({run.returncode}): {run.stderr.strip()[-300:]}")
        return None
    rows = []
    for line in run.stderr.splitlines():
        fields = line.split(",")
        if len(fields) < 3 or not re.match(r"^[0-9.]+$", fields[0]):
            continue
        name = fields[2].replace("syscalls:sys_enter_", "")
        value = float(fields[0])
        if name == "task-clock":
            rows.append(("CPU µs (all threads)", value * 1000 / steps))
        else:
            rows.append((name, value / steps))
    return rows


def thread_times() -> dict[tuple[str, str, str], int]:
    """(process, thread, tid) -> utime + stime in clock ticks, for the node processes."""
    times = {}
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            comm = pathlib.Path(f"/proc/{pid}/comm").read_text().strip()
            if comm not in NODES:
                continue
            for tid in os.listdir(f"/proc/{pid}/task"):
                stat = pathlib.Path(f"/proc/{pid}/task/{tid}/stat").read_text()
                name = stat[stat.index("(") + 1:stat.rindex(")")]
                fields = stat[stat.rindex(")") + 2:].split()
                times[(comm, name, tid)] = int(fields[11]) + int(fields[12])
        except (FileNotFoundError, ProcessLookupError, ValueError):
            continue
    return times


def per_thread(binary: str, steps: int, settle: float, window: float) -> tuple[list, float]:
    """Each node thread's CPU share over `window` s after `settle` s, and the run's rate."""
    with tempfile.TemporaryDirectory() as tmp:
        proc = subprocess.Popen(launch_command(binary, steps, pathlib.Path(tmp) / "bag"),
                                stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, env=env())
        time.sleep(settle)
        before, t0 = thread_times(), time.monotonic()
        time.sleep(window)
        after, elapsed = thread_times(), time.monotonic() - t0
        out, _ = proc.communicate()
    if proc.returncode != 0:
        raise SystemExit(f"launch failed ({proc.returncode})")
    rate = float(re.search(r"([0-9.]+) steps/s\)", out).group(1))
    tick = os.sysconf("SC_CLK_TCK")
    shares = sorted(((k[0], k[1], (after[k] - before[k]) / tick / elapsed) for k in after if k in before),
                    key=lambda r: -r[2])
    return [r for r in shares if r[2] > 0.005], rate


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--steps", type=int, default=40000)
    parser.add_argument("--bin", default=str(REPO / "target" / "release" / "causal-arm"))
    args = parser.parse_args()
    counts = syscalls_per_step(args.bin, args.steps)
    if counts:
        print(f"\nper step of `launch exp1 --steps {args.steps}` (whole run, start-up included)")
        print(f"{'what':<24} {'per step':>10}")
        for name, value in counts:
            print(f"{name:<24} {value:>10.1f}")
    shares, rate = per_thread(args.bin, args.steps, settle=5.0, window=6.0)
    print(f"\nthreads over 6 s in the middle of the run ({rate:.0f} steps/s over the whole run)")
    print(f"{'process':<18} {'thread':<18} {'% of a core':>12}")
    for process, thread, share in shares:
        print(f"{process:<18} {thread:<18} {share * 100:>11.1f}%")
    print(f"{'all':<37} {sum(s for _, _, s in shares) * 100:>11.1f}%")


if __name__ == "__main__":
    main()
