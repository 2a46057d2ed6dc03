#!/usr/bin/env python3
"""SHAP speed: ours (`causal-arm explain`) vs the `shap` library, side by side on the same
forward model, observations and background.

  Deep SHAP:   200 observations x 100 sampled background rows. Ours: `explain --method deep`
               (time = the attribution step, from explanation.json). Reference:
               shap.DeepExplainer on an equivalent torch module (standardisation, tanh layers,
               un-standardisation and the delta model's offset columns as torch ops), the same
               200 observations and 100 background rows read from our shap_values.safetensors.
               The attributions are compared (max difference / max |phi|).
  Kernel SHAP: 50 k-means centres (ours; shap gets the same weighted centres), 2M+2048
               coalitions, no L1 selection on either side. Ours on --kernel-obs observations,
               shap on --shap-kernel-obs (slow); compared per observation.

Both sides get the same thread count (torch.set_num_threads; numpy's BLAS through
OMP_NUM_THREADS/OPENBLAS_NUM_THREADS set by this script before importing numpy). Denormals
are flushed on the torch side as on ours. Run on a quiet machine:

  target/benchvenv/bin/pip install -r tests/bench/requirements-bench.txt
  target/benchvenv/bin/python tests/bench/shap_bench.py [--model models/paper_exp2 --bag bags/paper_exp2]

Without --model/--bag it makes a quick exp2 bag and a 3x256 FM first (a minute).
"""

import argparse
import json
import os
import pathlib
import subprocess
import sys
import tempfile
import time

REPO = pathlib.Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "tests" / "python"))


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--model", type=pathlib.Path)
    p.add_argument("--bag", type=pathlib.Path)
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--kernel-obs", type=int, default=20)
    p.add_argument("--shap-kernel-obs", type=int, default=4)
    p.add_argument("--bin", type=pathlib.Path, default=REPO / "target" / "release" / "causal-arm")
    args = p.parse_args()
    for var in ["OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"]:
        os.environ[var] = str(args.threads)

    import numpy as np
    import shap
    import torch
    from torch import nn

    from model_numpy import load_safetensors, numpy_predict

    torch.set_num_threads(args.threads)
    torch.set_flush_denormal(True)
    work = pathlib.Path(tempfile.mkdtemp(prefix="shap-bench-"))

    def cli(*a):
        r = subprocess.run([str(args.bin), *map(str, a)], capture_output=True, text=True)
        if r.returncode != 0:
            sys.exit(f"causal-arm {' '.join(map(str, a))} failed:\n{r.stderr}")
        return r

    model, bag = args.model, args.bag
    if model is None or bag is None:
        bag, model = work / "bag", work / "models"
        print("making a quick exp2 bag and FM (3x256) ...", file=sys.stderr)
        cli("generate", "exp2", "--profile", "quick", "--seed", "1", "--out", bag)
        cli("train", "--bag", bag, "--model", "fm", "--profile", "quick", "--folds", "5", "--max-folds", "1",
            "--cache", work / "cache", "--out", model)

    # Ours.
    t0 = time.perf_counter()
    cli("explain", "--model", model, "--bag", bag, "--method", "deep", "--samples", 200, "--background", 100,
        "--threads", args.threads, "--no-pair-plots", "--out", work / "deep")
    deep_wall = time.perf_counter() - t0
    deep = json.loads((work / "deep" / "explanation.json").read_text())
    cli("explain", "--model", model, "--bag", bag, "--method", "kernel", "--samples", args.kernel_obs,
        "--background", 50, "--threads", args.threads, "--no-pair-plots", "--out", work / "kernel")
    kernel = json.loads((work / "kernel" / "explanation.json").read_text())
    ours_deep = load_safetensors(work / "deep" / "shap_values.safetensors")
    ours_kernel = load_safetensors(work / "kernel" / "shap_values.safetensors")

    # The same function as a torch module.
    meta = json.loads((model / "fm.json").read_text())
    w = load_safetensors(model / "fm.safetensors")
    offset = meta["problem"]["offset_columns"]

    class Fm(nn.Module):
        def __init__(self):
            super().__init__()
            n = len(meta["architecture"]["hidden"]) + 1
            self.layers = nn.ModuleList()
            for i in range(n):
                weight = torch.tensor(w[f"layers.{i}.weight"])
                layer = nn.Linear(weight.shape[1], weight.shape[0]).double()
                layer.weight.data = weight
                layer.bias.data = torch.tensor(w[f"layers.{i}.bias"])
                self.layers.append(layer)
                if i < n - 1:
                    self.layers.append(nn.Tanh())
            for name in ["input.mean", "input.std", "output.mean", "output.std"]:
                self.register_buffer(name.replace(".", "_"), torch.tensor(w[name]))
            self.offset = None if offset is None else torch.tensor(offset)

        def forward(self, x):
            h = (x - self.input_mean) / self.input_std
            for layer in self.layers:
                h = layer(h)
            y = h * self.output_std + self.output_mean
            if self.offset is not None:
                y = y + x[:, self.offset]
            return y

    fm = Fm().eval()
    x = torch.tensor(ours_deep["observations"])
    bg = torch.tensor(ours_deep["background"])
    explainer = shap.DeepExplainer(fm, bg)
    t0 = time.perf_counter()
    theirs = explainer.shap_values(x)
    shap_deep_s = time.perf_counter() - t0
    theirs = np.stack(theirs, axis=-1) if isinstance(theirs, list) else np.asarray(theirs)
    deep_diff = np.abs(theirs - ours_deep["values"]).max() / np.abs(ours_deep["values"]).max()

    from shap.utils._legacy import DenseData

    n_in = ours_kernel["observations"].shape[1]
    data = DenseData(ours_kernel["background"].copy(), [str(i) for i in range(n_in)], None,
                     ours_kernel["background_weights"].copy())
    f = lambda rows: numpy_predict(model, "fm", rows)  # noqa: E731
    k = shap.KernelExplainer(f, data)
    obs = ours_kernel["observations"][: args.shap_kernel_obs]
    t0 = time.perf_counter()
    theirs_k = k.shap_values(obs, l1_reg=0, silent=True)
    shap_kernel_per_obs = (time.perf_counter() - t0) / len(obs)
    theirs_k = np.stack(theirs_k, axis=-1) if isinstance(theirs_k, list) else np.asarray(theirs_k)
    kernel_diff = (np.abs(theirs_k - ours_kernel["values"][: len(obs)]).max()
                   / np.abs(ours_kernel["values"][: len(obs)]).max())
    ours_kernel_per_obs = kernel["seconds"] / kernel["observations"]

    rows = [
        ("Deep SHAP, 200 obs x 100 background", deep["seconds"], shap_deep_s, 20),
        ("Kernel SHAP, per observation (50 k-means, 2M+2048)", ours_kernel_per_obs, shap_kernel_per_obs, 10),
    ]
    print(f"model {model} ({n_in} inputs -> {ours_deep['values'].shape[2]} outputs, "
          f"hidden {meta['architecture']['hidden']}), {args.threads} threads, shap {shap.__version__}, torch {torch.__version__}")
    print(f"{'run':<52} {'ours [s]':>10} {'shap [s]':>10} {'speed-up':>9} {'target':>7}")
    for name, ours, ref, target in rows:
        print(f"{name:<52} {ours:>10.3f} {ref:>10.3f} {ref / ours:>8.1f}x {target:>6}x")
    print(f"ours deep SHAP whole CLI run (bag from cache, model, figures): {deep_wall:.2f} s")
    print(f"agreement: deep max|ours - shap| = {deep_diff:.1e} of max|phi|; kernel (sampled, "
          f"{len(obs)} obs, independent draws) = {kernel_diff:.1e}")


if __name__ == "__main__":
    main()
