"""Our Kernel SHAP against the reference implementation, Python `shap.KernelExplainer`, on
the same function: a forward model written by `causal-arm train`, evaluated by a numpy
forward pass of its files, with the observations and background our explainer used (read
from its `shap_values.safetensors`)."""

import json

import numpy as np
import pytest

from conftest import bag_and_forward_model
from model_numpy import load_safetensors, numpy_predict

import shap  # noqa: E402  (pinned in requirements.txt: a missing reference must fail, not skip)


@pytest.fixture(scope="module")
def exp1_fm(run_cli, tmp_path_factory):
    d = tmp_path_factory.mktemp("shap")
    bag_and_forward_model(run_cli, d, ["exp1", "--profile", "quick", "--steps", "1500", "--seed", "8"],
                          ["--epochs", "10", "--folds", "2", "--max-folds", "1", "--fm-hidden", "64,64"])
    return d


def explain(run_cli, d, out, *args):
    r = run_cli("explain", "--model", d / "models", "--bag", d / "bag", "--cache", d / "cache", "--method", "kernel",
                "--no-pair-plots", "--out", d / out, *args, timeout=300)
    assert r.returncode == 0, r.stderr
    t, meta = load_safetensors(d / out / "shap_values.safetensors", with_metadata=True)
    assert meta["method"] == "kernel"
    return t


def reference(d, t, nsamples):
    """shap.KernelExplainer on the numpy model, our observations and background, no L1
    feature selection (ours has none); values as [obs, inputs, outputs]."""
    f = lambda x: numpy_predict(d / "models", "fm", x)  # noqa: E731
    explainer = shap.KernelExplainer(f, t["background"])
    values = explainer.shap_values(t["observations"], nsamples=nsamples, l1_reg=0, silent=True)
    values = np.stack(values, axis=-1) if isinstance(values, list) else np.asarray(values)
    return values, np.asarray(explainer.expected_value)


def test_exact_enumeration_equals_shap_kernel_explainer(exp1_fm, run_cli):
    # 17 inputs: 2^17 − 2 = 131,070 coalitions; both sides enumerate them all, so both give
    # the exact Shapley values of the same function and must agree to float rounding.
    t = explain(run_cli, exp1_fm, "exact", "--samples", "3", "--background", "8", "--background-kind", "sample",
                "--kernel-samples", "131072")
    ours = t["values"]
    assert ours.shape == (3, 17, 10)
    theirs, expected = reference(exp1_fm, t, nsamples=2**17)
    # Base values: mean of the model over the background, ours evaluated in f32.
    np.testing.assert_allclose(t["expected"], expected, rtol=0, atol=1e-6 * np.abs(expected).max())
    scale = np.abs(ours).max()
    # Both solve the same weighted least squares over 131k rows in f64; the model is
    # evaluated in f32 by us and in f64 by numpy, which bounds the agreement at ~1e-6 of the
    # largest attribution.
    print(f"exact: max abs diff {np.abs(ours - theirs).max() / scale:.2e} of max abs phi")
    assert np.abs(ours - theirs).max() <= 1e-5 * scale, np.abs(ours - theirs).max() / scale
    # Efficiency, and the outputs are the model files' forward pass.
    f_x = numpy_predict(exp1_fm / "models", "fm", t["observations"])
    np.testing.assert_allclose(t["outputs"], f_x, rtol=1e-5, atol=1e-6 * np.abs(f_x).max())
    np.testing.assert_allclose(ours.sum(axis=1), t["outputs"] - t["expected"], atol=1e-9 * scale)


def test_sampled_kernel_shap_agrees_with_shap_within_sampling_noise(exp1_fm, run_cli):
    # Default budget on both sides (2·17 + 2048 coalitions of 131,070, each side its own
    # random draw), k-means background as `shap.kmeans` would give. The tolerance is set
    # from the measured spread between two of shap's own seeds (see below), not guessed.
    t = explain(run_cli, exp1_fm, "sampled", "--samples", "4", "--background", "10")
    assert not np.allclose(t["background_weights"], t["background_weights"][0])  # k-means weights
    f = lambda x: numpy_predict(exp1_fm / "models", "fm", x)  # noqa: E731
    from shap.utils._legacy import DenseData

    data = DenseData(t["background"].copy(), [str(i) for i in range(17)], None, t["background_weights"].copy())
    runs = []
    for seed in (0, 1):
        np.random.seed(seed)
        values = shap.KernelExplainer(f, data).shap_values(t["observations"], l1_reg=0, silent=True)
        runs.append(np.stack(values, axis=-1) if isinstance(values, list) else np.asarray(values))
    ours = t["values"]
    scale = np.abs(runs[0]).max(axis=(1, 2), keepdims=True)  # per observation
    ours_vs_shap = (np.abs(ours - runs[0]) / scale).max()
    shap_vs_shap = (np.abs(runs[1] - runs[0]) / scale).max()
    # Ours differs from shap no more than shap differs from itself (with a margin of 3× and
    # a floor of 1 % of the largest attribution), and the pattern is the same.
    print(f"sampled: ours vs shap {ours_vs_shap:.2e}, shap vs shap {shap_vs_shap:.2e} of max abs phi")
    assert ours_vs_shap <= max(3 * shap_vs_shap, 0.01), (ours_vs_shap, shap_vs_shap)
    assert np.corrcoef(ours.ravel(), runs[0].ravel())[0, 1] > 0.999
    # A real bug would not hide in that tolerance: swapping two action columns' attributions
    # (a0 and a1) moves the comparison far outside it.
    swapped = ours.copy()
    swapped[:, [10, 11]] = swapped[:, [11, 10]]
    assert (np.abs(swapped - runs[0]) / scale).max() > 10 * max(3 * shap_vs_shap, 0.01)


def test_deep_and_kernel_agree_on_the_dominant_links(exp1_fm, run_cli):
    # Different methods, same model: each joint's action is the strongest on its own angle.
    for method in ["deep", "kernel"]:
        r = run_cli("explain", "--model", exp1_fm / "models", "--bag", exp1_fm / "bag", "--cache", exp1_fm / "cache",
                    "--method", method, "--samples", "40", "--no-pair-plots", "--out", exp1_fm / f"links-{method}",
                    timeout=300)
        assert r.returncode == 0, r.stderr
        report = json.loads((exp1_fm / f"links-{method}" / "relevance.json").read_text())
        for j in range(7):
            verdict = next(v for v in report["states"] if v["name"] == f"theta{j}")
            assert verdict["strongest_action"] == f"a{j}", (method, verdict)
