#!/usr/bin/env python3
"""Two builds' DDS graphs, interleaved: the only fair A/B on this VM, whose speed drifts by up
to 40 % within an hour (runs of one build an hour apart compare the VM, not the builds).

Each round runs `launch exp1` once per build and shard count, alternating builds, and
prints each run's steps/s over the whole launch, steps/s while stepping (see
datagen_bench.py), the seconds spent besides stepping (start-up, discovery, the end) and
steps lost; then the means. A build is a directory holding
`causal-arm` and the node binaries (copy them out of target/release before rebuilding).
Usage (starts DDS participants: inside tests/netns-run, on a quiet machine):
  tests/netns-run target/pyvenv/bin/python tests/bench/dds_ab.py A_DIR B_DIR [C_DIR …] [--steps N] [--rounds R] [--shards 1,2]
"""

import argparse
import pathlib

from datagen_bench import ours_dds


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("builds", nargs="+", help="two or more build directories, run in turn")
    parser.add_argument("--steps", type=int, default=20000)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--shards", default="1,2")
    args = parser.parse_args()
    if len(args.builds) < 2:
        parser.error("give at least two builds to compare")
    results: dict[tuple[str, int], list[tuple[float, float, int]]] = {}
    for _ in range(args.rounds):
        for shards in (int(s) for s in args.shards.split(",")):
            for build in args.builds:
                run = ours_dds(str(pathlib.Path(build) / "causal-arm"), args.steps, shards)
                results.setdefault((build, shards), []).append(run)
                whole, stepping, lost = run
                besides = args.steps / whole - args.steps / stepping
                print(f"{build:<24} shards={shards}: whole {whole:6.0f}  stepping {stepping:6.0f}  "
                      f"besides stepping {besides:5.2f} s  lost {lost}", flush=True)
    print()
    for (build, shards), runs in results.items():
        whole = sum(r[0] for r in runs) / len(runs)
        stepping = sum(r[1] for r in runs) / len(runs)
        lost = sum(r[2] for r in runs)
        besides = sum(args.steps / r[0] - args.steps / r[1] for r in runs) / len(runs)
        print(f"{build:<24} shards={shards}: mean whole {whole:6.0f}  mean stepping {stepping:6.0f}  "
              f"mean besides stepping {besides:5.2f} s  lost {lost}")


if __name__ == "__main__":
    main()
