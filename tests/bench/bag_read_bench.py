#!/usr/bin/env python3
"""Bag reading speed: the checked reader against a reference build and an independent reader.

Times `causal-arm bag info BAG` (open: every chunk decompressed and checked; then every
message read) for each binary given, alternated round by round, beside the MCAP library's
Python stream reader going through every record of the same file (the independent
reference). Prints MB/s and messages/s. Usage:
  target/pyvenv/bin/python tests/bench/bag_read_bench.py --bag bags/paper_exp2_mws \
      --bin NEW=target/release/causal-arm --bin OLD=/path/to/old/causal-arm [--rounds 2]
Run it on a quiet machine (nothing else building or training).
"""

import argparse
import json
import pathlib
import subprocess
import time


def ours(binary: str, bag: pathlib.Path) -> tuple[float, int]:
    start = time.perf_counter()
    r = subprocess.run([binary, "bag", "info", str(bag)], capture_output=True, text=True, check=True)
    return time.perf_counter() - start, json.loads(r.stdout)["message_count"]


def python_stream_reader(mcap_file: pathlib.Path) -> tuple[float, int]:
    from mcap.records import Message
    from mcap.stream_reader import StreamReader

    start = time.perf_counter()
    n = 0
    with open(mcap_file, "rb") as f:
        for record in StreamReader(f).records:
            n += isinstance(record, Message)
    return time.perf_counter() - start, n


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--bag", type=pathlib.Path, required=True)
    parser.add_argument("--bin", action="append", required=True, help="NAME=PATH (repeat)")
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--no-python", action="store_true", help="skip the (slow) Python reference")
    args = parser.parse_args()
    mcap_file = next(args.bag.glob("*.mcap")) if args.bag.is_dir() else args.bag
    size_mb = mcap_file.stat().st_size / 1e6
    runs = {}
    for _ in range(args.rounds):
        for named in args.bin:
            name, path = named.split("=", 1)
            runs.setdefault(f"causal-arm bag info ({name})", []).append(ours(path, args.bag))
    if not args.no_python:
        runs["mcap Python StreamReader (reference)"] = [python_stream_reader(mcap_file)]
    print(f"\n{mcap_file} ({size_mb:.0f} MB)")
    print(f"{'run':<44} {'seconds':>16} {'MB/s':>8} {'messages/s':>12}")
    for name, results in runs.items():
        seconds = [s for s, _ in results]
        best = min(seconds)
        shown = " / ".join(f"{s:.2f}" for s in seconds)
        print(f"{name:<44} {shown:>16} {size_mb / best:>8.0f} {results[0][1] / best:>12.0f}")


if __name__ == "__main__":
    main()
