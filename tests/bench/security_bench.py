#!/usr/bin/env python3
"""What SROS2 security costs the graph: `causal-arm launch exp1` secured vs. unsecured.

Runs the same launch (seed, steps) alternately without security (the reference) and with a
fresh keystore (Enforce, one enclave for every node via `--ros-args --enclave`), and prints
per mode: runs that completed, median wall time, median steps/s, and the bag's size. A
secured run that does not complete counts as a failure, not as a slow run.

  tests/netns-run target/pyvenv/bin/python tests/bench/security_bench.py [--runs 5] [--steps 5000] [--bin target/release/causal-arm]

Starts DDS participants: run it inside tests/netns-run, on a quiet machine.
"""

import argparse
import os
import pathlib
import re
import statistics
import subprocess
import tempfile
import time

REPO = pathlib.Path(__file__).resolve().parents[2]
DOMAIN = "43"
ENCLAVE = "/causal_arm"


def cli(binary, *args, env=None, timeout=600):
    return subprocess.run([str(binary), *map(str, args)], capture_output=True, text=True,
                          timeout=timeout, env={**os.environ, **(env or {})})


def keystore(binary, root):
    env = {"ROS_DOMAIN_ID": DOMAIN}
    for args in (("create-keystore", root), ("create-enclave", root, ENCLAVE)):
        r = cli(binary, "security", *args, env=env)
        if r.returncode != 0:
            raise SystemExit(r.stderr)


def launch(binary, out, steps, secured, root):
    env = {"ROS_DOMAIN_ID": DOMAIN, "RUST_LOG": "error"}
    extra = []
    if secured:
        env.update(ROS_SECURITY_ENABLE="true", ROS_SECURITY_STRATEGY="Enforce",
                   ROS_SECURITY_KEYSTORE=str(root))
        extra = ["--ros-args", "--enclave", ENCLAVE]
    start = time.monotonic()
    r = cli(binary, "launch", "exp1", "--steps", steps, "--seed", "4", "--out", out, *extra, env=env)
    wall = time.monotonic() - start
    done = re.search(rf"\((\d+) of {steps} steps", r.stdout)
    ok = r.returncode == 0 and done is not None and int(done[1]) == steps
    size = sum(f.stat().st_size for f in pathlib.Path(out).glob("*")) if ok else 0
    return ok, wall, size


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--steps", type=int, default=5000)
    ap.add_argument("--bin", default=str(REPO / "target" / "release" / "causal-arm"))
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        root = pathlib.Path(tmp) / "keystore"
        keystore(a.bin, root)
        results = {False: [], True: []}
        for i in range(a.runs):
            for secured in (False, True):
                out = pathlib.Path(tmp) / f"bag_{i}_{int(secured)}"
                results[secured].append(launch(a.bin, out, a.steps, secured, root))
                ok, wall, _ = results[secured][-1]
                print(f"run {i + 1} {'secured' if secured else 'plain  '}: "
                      f"{'complete' if ok else 'FAILED'} in {wall:.1f} s", flush=True)
    print(f"\nlaunch exp1 --steps {a.steps}, {a.runs} runs each, {a.bin}")
    print(f"{'mode':<26}{'complete':>10}{'median s':>10}{'steps/s':>10}{'bag MiB':>10}")
    for secured, label in ((False, "unsecured (reference)"), (True, "SROS2 Enforce")):
        rows = results[secured]
        good = [w for ok, w, _ in rows if ok]
        sizes = [s for ok, _, s in rows if ok]
        med = statistics.median(good) if good else float("nan")
        mib = statistics.median(sizes) / 2**20 if sizes else float("nan")
        print(f"{label:<26}{len(good):>5} / {len(rows):<3}{med:>10.2f}{a.steps / med:>10.0f}{mib:>10.2f}")


if __name__ == "__main__":
    main()
