#!/usr/bin/env python3
"""MLP training speed: ours (crates/mlp) vs PyTorch CPU, side by side on the same data.

For each forward model of the paper and each batch size, trains one epoch (after a warm-up)
on the same random rows, first with our trainer (the release example `train_bench` of
crates/mlp, run as a subprocess on raw f32 files this script writes), then with PyTorch:
  * exp1 FM: 17 inputs -> 3 x 256 tanh -> heads theta 7, ef 3
  * exp2 FM: 31 inputs -> 3 x 256 tanh -> heads obj_pos 3, obj_rot 3, colour 3, theta 7,
    ef_pos 3, ef_rot 3, magnet 1
Both sides: loss = sum over heads of the per-head mean squared error, Adam (lr 1e-3,
betas 0.9/0.999, eps 1e-8), the same thread count (torch.set_num_threads), denormals flushed,
one shuffle per epoch into contiguous tensors and then contiguous batch slices; the timed
epoch includes that shuffle on both sides. Prints a table of samples/s and the ratio.

PyTorch lives in its own venv, not the test venv (the PyPI wheel pulls CUDA libraries,
about 5.4 GB; there is no CPU-only index here). Create it once, then run:
  python3 -m venv target/benchvenv
  target/benchvenv/bin/pip install -r tests/bench/requirements-bench.txt
  target/benchvenv/bin/python tests/bench/train_bench.py [--rows 200000] [--threads 2]
      [--models exp1,exp2] [--batches 256,1024] [--bin target/release/examples/train_bench]
The script builds the example (`cargo build --release -p causal_arm_mlp --example
train_bench`) unless --bin is given or --no-build is passed. Run it on a quiet machine
(nothing else building): both sides use every core they are given.
"""

import argparse
import json
import pathlib
import subprocess
import sys
import tempfile
import time

import numpy as np
import torch
from torch import nn

REPO = pathlib.Path(__file__).resolve().parents[2]
MODELS = {
    "exp1": (17, [("theta", 7), ("ef", 3)]),
    "exp2": (31, [("obj_pos", 3), ("obj_rot", 3), ("colour", 3), ("theta", 7), ("ef_pos", 3),
                  ("ef_rot", 3), ("magnet", 1)]),
}
HIDDEN = [256, 256, 256]


def make_data(model: str, rows: int, seed: int = 0):
    inputs, heads = MODELS[model]
    outputs = sum(size for _, size in heads)
    rng = np.random.default_rng(seed)
    x = rng.uniform(-1.0, 1.0, (rows, inputs)).astype(np.float32)
    y = rng.uniform(-1.0, 1.0, (rows, outputs)).astype(np.float32)
    return x, y


def torch_epoch_speed(model: str, x: np.ndarray, y: np.ndarray, batch: int, warmup_rows: int,
                      seed: int = 0) -> tuple[float, float]:
    """Samples/s of one timed epoch, and its mean loss."""
    inputs, heads = MODELS[model]
    torch.manual_seed(seed)
    widths = [inputs] + HIDDEN
    layers = []
    for a, b in zip(widths[:-1], widths[1:]):
        layers += [nn.Linear(a, b), nn.Tanh()]
    layers.append(nn.Linear(widths[-1], sum(size for _, size in heads)))
    net = nn.Sequential(*layers)
    opt = torch.optim.Adam(net.parameters(), lr=1e-3, betas=(0.9, 0.999), eps=1e-8)
    bounds = []
    start = 0
    for _, size in heads:
        bounds.append((start, start + size))
        start += size
    xt = torch.from_numpy(x)
    yt = torch.from_numpy(y)
    gen = torch.Generator().manual_seed(seed)

    def epoch(xe: torch.Tensor, ye: torch.Tensor) -> float:
        n = xe.shape[0]
        perm = torch.randperm(n, generator=gen)
        xs = xe[perm].contiguous()
        ys = ye[perm].contiguous()
        total = 0.0
        for s in range(0, n, batch):
            xb = xs[s:s + batch]
            yb = ys[s:s + batch]
            pred = net(xb)
            loss = sum(nn.functional.mse_loss(pred[:, a:b], yb[:, a:b]) for a, b in bounds)
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
            total += loss.item() * xb.shape[0]
        return total / n

    epoch(xt[:warmup_rows], yt[:warmup_rows])
    t0 = time.perf_counter()
    mean_loss = epoch(xt, yt)
    seconds = time.perf_counter() - t0
    return x.shape[0] / seconds, mean_loss


def ours_speed(binary: pathlib.Path, model: str, xfile: pathlib.Path, yfile: pathlib.Path,
               batch: int, warmup_rows: int, threads: int) -> dict:
    out = subprocess.run(
        [str(binary), "--model", model, "--batch", str(batch), "--x", str(xfile), "--y", str(yfile),
         "--warmup-rows", str(warmup_rows), "--threads", str(threads)],
        check=True, capture_output=True, text=True).stdout
    results = [json.loads(line) for line in out.splitlines() if line.startswith("{")]
    if len(results) != 1:
        sys.exit(f"unexpected output from {binary}:\n{out}")
    return results[0]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rows", type=int, default=200_000)
    ap.add_argument("--warmup-rows", type=int, default=20_000)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--models", default="exp1,exp2")
    ap.add_argument("--batches", default="256,1024")
    ap.add_argument("--bin", type=pathlib.Path, help="prebuilt train_bench example")
    ap.add_argument("--no-build", action="store_true", help="use target/release/examples/train_bench as is")
    args = ap.parse_args()

    binary = args.bin or REPO / "target/release/examples/train_bench"
    if args.bin is None and not args.no_build:
        subprocess.run(["cargo", "build", "--release", "-q", "-p", "causal_arm_mlp", "--example", "train_bench"],
                       cwd=REPO, check=True)
    if not binary.exists():
        sys.exit(f"{binary} not found")

    torch.set_num_threads(args.threads)
    torch.set_flush_denormal(True)
    print(f"torch {torch.__version__}, {args.threads} threads, {args.rows} rows, one epoch after a "
          f"{args.warmup_rows}-row warm-up", flush=True)
    rows_out = []
    with tempfile.TemporaryDirectory() as tmp:
        for model in args.models.split(","):
            x, y = make_data(model, args.rows)
            xfile = pathlib.Path(tmp) / f"{model}_x.f32"
            yfile = pathlib.Path(tmp) / f"{model}_y.f32"
            x.astype("<f4").tofile(xfile)
            y.astype("<f4").tofile(yfile)
            for batch in (int(b) for b in args.batches.split(",")):
                ours = ours_speed(binary, model, xfile, yfile, batch, args.warmup_rows, args.threads)
                theirs, torch_loss = torch_epoch_speed(model, x, y, batch, args.warmup_rows)
                ratio = ours["samples_per_s"] / theirs
                rows_out.append((model, batch, ours["samples_per_s"], theirs, ratio))
                print(f"  {model} batch {batch}: ours {ours['samples_per_s']:.0f}/s (loss {ours['loss']:.4f}), "
                      f"torch {theirs:.0f}/s (loss {torch_loss:.4f})", flush=True)
    print()
    print(f"{'model':<6} {'batch':>6} {'ours samples/s':>15} {'PyTorch samples/s':>18} {'ratio':>6}")
    for model, batch, ours, theirs, ratio in rows_out:
        print(f"{model:<6} {batch:>6} {ours:>15.0f} {theirs:>18.0f} {ratio:>6.2f}")


if __name__ == "__main__":
    main()
