#!/usr/bin/env python3
"""SHAP speed: ours (`causal-arm explain`) vs the `shap` library, side by side in the same
run, on the same exp2 forward model (31 inputs -> 23 outputs), observations and background.

  Deep SHAP:   200 observations x 100 sampled background rows. Ours: `explain --method deep
               --threads T` (time = the attribution step, "seconds" of explanation.json; the
               whole CLI run is printed too). Reference: shap.DeepExplainer on an equivalent
               torch module in float64 (standardisation, tanh layers, un-standardisation and
               the delta model's offset columns as torch ops; ours also computes in f64), on
               the same 200 observations and 100 background rows read from our
               shap_values.safetensors. Attributions compared: max |ours - shap| / max |phi|.
  Kernel SHAP: 50 weighted k-means centres (ours; shap gets the same centres and weights,
               i.e. what shap.kmeans hands it, so the two explain the same function), default
               budget 2M+2048 coalitions, no L1 feature selection on either side. shap's
               model is the numpy forward pass of the model files in f64 (the tests' oracle);
               a second row gives shap with the model in f32 numpy, as ours evaluates it.
               Ours on --kernel-obs observations (default 200, the paper's analysis); shap on
               --shap-kernel-obs of them spread evenly (slow), timed per observation after a
               separately timed first call (shap's one-time start-up, ~1 s), and extrapolated
               to ours' count (printed as such). Each side samples its own coalitions, so the
               comparison is within sampling noise; a second shap seed on a few observations
               gives that noise for context.

Both sides get the same thread count (torch.set_num_threads; numpy's BLAS through
OMP_NUM_THREADS/OPENBLAS_NUM_THREADS set before numpy is imported). Denormals are flushed on
the torch side as on ours. The 1-minute load average is printed before and after: run it
on a quiet machine (nothing else building). Venv (see train_bench.py):

  target/benchvenv/bin/pip install -r tests/bench/requirements-bench.txt
  target/benchvenv/bin/python tests/bench/shap_bench.py [--model models/paper_exp2 --bag bags/paper_exp2]

Without --model/--bag it makes a quick exp2 bag and FM first (a minute). The binary is
target/release/causal-arm (`cargo build --release -p causal_arm_cli`), or --bin.
"""

import argparse
import json
import os
import pathlib
import shutil
import subprocess
import sys
import tempfile
import time

REPO = pathlib.Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "tests" / "python"))

TARGETS = {"deep": 20, "kernel": 10}


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--model", type=pathlib.Path, help="model directory with fm.json/fm.safetensors (exp2)")
    p.add_argument("--bag", type=pathlib.Path, help="exp2 bag the observations are drawn from")
    p.add_argument("--cache", type=pathlib.Path, help="dataset cache (default: the CLI's)")
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--kernel-obs", type=int, default=200)
    p.add_argument("--shap-kernel-obs", type=int, default=10)
    p.add_argument("--bin", type=pathlib.Path, default=REPO / "target" / "release" / "causal-arm")
    p.add_argument("--keep", action="store_true", help="keep the work directory (explanations, quick bag/model)")
    args = p.parse_args()
    for var in ["OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"]:
        os.environ[var] = str(args.threads)

    import numpy as np
    import shap
    import torch
    from shap.utils._legacy import DenseData
    from torch import nn

    from model_numpy import load_safetensors, numpy_predict

    torch.set_num_threads(args.threads)
    torch.set_flush_denormal(True)
    if not args.bin.exists():
        sys.exit(f"{args.bin} not found: cargo build --release -p causal_arm_cli")
    work = pathlib.Path(tempfile.mkdtemp(prefix="shap-bench-"))
    load_before = os.getloadavg()[0]

    def cli(*a):
        r = subprocess.run([str(args.bin), *map(str, a)], capture_output=True, text=True)
        if r.returncode != 0:
            sys.exit(f"causal-arm {' '.join(map(str, a))} failed:\n{r.stderr}")
        return r

    model, bag = args.model, args.bag
    cache = ["--cache", args.cache] if args.cache else []
    if model is None or bag is None:
        bag, model = work / "bag", work / "models"
        cache = ["--cache", work / "cache"]
        print("making a quick exp2 bag and FM ...", file=sys.stderr, flush=True)
        cli("generate", "exp2", "--profile", "quick", "--seed", "1", "--out", bag)
        cli("train", "--bag", bag, "--model", "fm", "--profile", "quick", "--folds", "5", "--max-folds", "1",
            *cache, "--out", model)
    meta = json.loads((model / "fm.json").read_text())
    if len(meta["problem"]["input_names"]) != 31:
        sys.exit(f"{model}: expected an exp2 forward model (31 inputs)")

    # ---- ours --------------------------------------------------------------------------
    print("ours: deep ...", file=sys.stderr, flush=True)
    cli("explain", "--model", model, "--bag", bag, *cache, "--method", "deep", "--samples", 200,
        "--background", 100, "--threads", args.threads, "--no-pair-plots", "--out", work / "warm")  # dataset cache
    t0 = time.perf_counter()
    cli("explain", "--model", model, "--bag", bag, *cache, "--method", "deep", "--samples", 200,
        "--background", 100, "--threads", args.threads, "--no-pair-plots", "--out", work / "deep")
    deep_wall = time.perf_counter() - t0
    deep = json.loads((work / "deep" / "explanation.json").read_text())
    print("ours: kernel ...", file=sys.stderr, flush=True)
    t0 = time.perf_counter()
    cli("explain", "--model", model, "--bag", bag, *cache, "--method", "kernel", "--samples", args.kernel_obs,
        "--background", 50, "--threads", args.threads, "--no-pair-plots", "--out", work / "kernel")
    kernel_wall = time.perf_counter() - t0
    kernel = json.loads((work / "kernel" / "explanation.json").read_text())
    ours_deep = load_safetensors(work / "deep" / "shap_values.safetensors")
    ours_kernel = load_safetensors(work / "kernel" / "shap_values.safetensors")
    n_in, n_out = ours_deep["values"].shape[1:]

    # ---- the same function as a torch module (float64, like our Deep SHAP) -------------
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
    with torch.no_grad():
        torch_out = fm(x).numpy()
    forward_diff = np.abs(torch_out - numpy_predict(model, "fm", ours_deep["observations"])).max()
    ours_out_diff = np.abs(torch_out - ours_deep["outputs"]).max()

    # ---- shap.DeepExplainer ---------------------------------------------------------------
    print("shap: deep ...", file=sys.stderr, flush=True)
    explainer = shap.DeepExplainer(fm, torch.tensor(ours_deep["background"]))
    explainer.shap_values(x[:1], check_additivity=False)  # warm-up, not timed (ours: a separate warm run)
    t0 = time.perf_counter()
    theirs = explainer.shap_values(x, check_additivity=False)
    shap_deep_s = time.perf_counter() - t0
    theirs = np.stack(theirs, axis=-1) if isinstance(theirs, list) else np.asarray(theirs)
    deep_scale = np.abs(ours_deep["values"]).max()
    deep_diff = np.abs(theirs - ours_deep["values"]).max() / deep_scale
    deep_where = np.unravel_index(np.abs(theirs - ours_deep["values"]).argmax(), theirs.shape)
    shap_eff = np.abs(theirs.sum(axis=1) - (torch_out - np.asarray(explainer.expected_value))).max() / deep_scale
    ours_eff = np.abs(ours_deep["values"].sum(axis=1) - (ours_deep["outputs"] - ours_deep["expected"])).max() / deep_scale

    # ---- shap.KernelExplainer ----------------------------------------------------------
    print("shap: kernel ...", file=sys.stderr, flush=True)
    data = DenseData(ours_kernel["background"].copy(), [str(i) for i in range(n_in)], None,
                     ours_kernel["background_weights"].copy())
    f = lambda rows: numpy_predict(model, "fm", rows)  # noqa: E731
    # shap's first call carries a one-time start-up (about 0.9 s here: lazy imports, numba);
    # it is timed on its own, then the steady state on observations spread evenly over the
    # ones ours explained (ours' time is their average).
    n_all = len(ours_kernel["observations"])
    picks = np.unique(np.linspace(0, n_all - 1, min(args.shap_kernel_obs, n_all)).round().astype(int))
    obs = ours_kernel["observations"][picks]
    np.random.seed(0)
    k = shap.KernelExplainer(f, data)
    t0 = time.perf_counter()
    k.shap_values(obs[:1], l1_reg=0, silent=True)
    shap_kernel_first = time.perf_counter() - t0
    t0 = time.perf_counter()
    theirs_k = k.shap_values(obs, l1_reg=0, silent=True)
    shap_kernel_per_obs = (time.perf_counter() - t0) / len(obs)
    shap_kernel_startup = max(shap_kernel_first - shap_kernel_per_obs, 0.0)
    theirs_k = np.stack(theirs_k, axis=-1) if isinstance(theirs_k, list) else np.asarray(theirs_k)
    ours_k = ours_kernel["values"][picks]
    per_obs_scale = np.abs(theirs_k).max(axis=(1, 2), keepdims=True)
    kernel_diff = (np.abs(theirs_k - ours_k) / per_obs_scale).max()
    kernel_corr = np.corrcoef(theirs_k.ravel(), ours_k.ravel())[0, 1]
    # The same reference with the model in f32 numpy (ours evaluates the model in f32 too):
    # the model is ~95 % of shap's time, so its precision moves the ratio a lot.
    w32 = {name: v.astype(np.float32) for name, v in w.items()}
    n_layers = len(meta["architecture"]["hidden"]) + 1

    def f32(rows):
        rows = rows.astype(np.float32)
        h = (rows - w32["input.mean"]) / w32["input.std"]
        for i in range(n_layers):
            h = h @ w32[f"layers.{i}.weight"].T + w32[f"layers.{i}.bias"]
            if i < n_layers - 1:
                h = np.tanh(h)
        y = h * w32["output.std"] + w32["output.mean"]
        return (y if offset is None else y + rows[:, offset]).astype(np.float64)

    np.random.seed(0)
    t0 = time.perf_counter()
    shap.KernelExplainer(f32, data).shap_values(obs, l1_reg=0, silent=True)
    shap_kernel32_per_obs = (time.perf_counter() - t0) / len(obs)
    n_noise = min(3, len(obs))
    np.random.seed(1)
    again = shap.KernelExplainer(f, data).shap_values(obs[:n_noise], l1_reg=0, silent=True)
    again = np.stack(again, axis=-1) if isinstance(again, list) else np.asarray(again)
    shap_noise = (np.abs(again - theirs_k[:n_noise]) / per_obs_scale[:n_noise]).max()
    ours_noise_vs = (np.abs(ours_k[:n_noise] - theirs_k[:n_noise]) / per_obs_scale[:n_noise]).max()
    ours_kernel_per_obs = kernel["seconds"] / kernel["observations"]
    load_after = os.getloadavg()[0]

    # ---- table -------------------------------------------------------------------------
    n_k = kernel["observations"]
    print()
    print(f"model {model} ({n_in} inputs -> {n_out} outputs, hidden {meta['architecture']['hidden']}), "
          f"{args.threads} threads, shap {shap.__version__}, torch {torch.__version__}, "
          f"load average {load_before:.2f} before / {load_after:.2f} after")
    print(f"{'run':<58} {'ours [s]':>10} {'shap [s]':>10} {'speed-up':>9} {'target':>7}")
    rows = [
        ("Deep SHAP, 200 obs x 100 background (attribution only)", deep["seconds"], shap_deep_s, "deep"),
        ("Kernel SHAP, per observation (50 k-means, 2M+2048)", ours_kernel_per_obs, shap_kernel_per_obs, "kernel"),
        ("  same, shap's model in f32 numpy (ours: f32)", ours_kernel_per_obs, shap_kernel32_per_obs, "kernel"),
        (f"Kernel SHAP, {n_k} obs (shap extrapolated from {len(obs)} obs)",
         kernel["seconds"], shap_kernel_startup + shap_kernel_per_obs * n_k, "kernel"),
    ]
    for name, ours, ref, target in rows:
        print(f"{name:<58} {ours:>10.3f} {ref:>10.3f} {ref / ours:>8.1f}x {TARGETS[target]:>6}x")
    print(f"shap Kernel SHAP: steady state timed on {len(obs)} of ours' {n_k} observations (evenly spread), "
          f"after a first call of {shap_kernel_first:.2f} s (one-time start-up {shap_kernel_startup:.2f} s, "
          f"added once to the extrapolation)")
    print(f"ours, whole CLI run (dataset from cache, model, figures, files): deep {deep_wall:.2f} s, "
          f"kernel {kernel_wall:.2f} s")
    print(f"forward pass: torch vs numpy {forward_diff:.1e}, torch vs our `outputs` {ours_out_diff:.1e}")
    print(f"deep agreement: max|ours - shap| = {deep_diff:.1e} of max|phi| ({deep_scale:.3g}; worst at obs "
          f"{deep_where[0]}, input {meta['problem']['input_names'][deep_where[1]]}, output "
          f"{meta['problem']['output_names'][deep_where[2]]}); efficiency gap ours {ours_eff:.1e}, shap {shap_eff:.1e}")
    print(f"kernel agreement ({len(obs)} obs, independent samples): max|ours - shap| = {kernel_diff:.1e} of "
          f"max|phi| per obs, correlation {kernel_corr:.6f}; on {n_noise} obs ours vs shap {ours_noise_vs:.1e}, "
          f"shap seed 0 vs seed 1 {shap_noise:.1e}")
    if args.keep:
        print(f"work directory kept: {work}")
    else:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
