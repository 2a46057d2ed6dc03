"""`causal-arm train` and `rollout` from the command line: outputs, and clear errors with
exit code 1 for bad input (unknown model, other experiment's bag, corrupt files, …)."""

import json

import pytest


@pytest.fixture(scope="module")
def bags(run_cli, tmp_path_factory):
    d = tmp_path_factory.mktemp("train_cli")
    r = run_cli("generate", "exp1", "--steps", "1500", "--seed", "4", "--out", d / "exp1")
    assert r.returncode == 0, r.stderr
    r = run_cli("generate", "exp2", "--episodes", "2", "--seed", "4", "--out", d / "exp2")
    assert r.returncode == 0, r.stderr
    return d


def train(run_cli, bags, *args):
    defaults = {"--epochs": "2", "--folds": "2", "--fm-hidden": "16", "--im-hidden": "16"}
    extra = [x for k, v in defaults.items() if k not in args for x in (k, v)]
    return run_cli("train", "--cache", bags / "cache", *extra, *args, timeout=300)


def test_train_writes_models_and_metrics_beside_the_paper(run_cli, bags):
    out = bags / "models1"
    r = train(run_cli, bags, "--bag", bags / "exp1", "--model", "fm", "--out", out)
    assert r.returncode == 0, r.stderr
    assert "fm/theta" in r.stdout and "fm/ef" in r.stdout and "3.400e-3 rad" in r.stdout
    # stderr is a pipe here, where no bar can draw: plain progress lines stand in for it.
    assert "training fm fold 1/2: 2 epochs on" in r.stderr, r.stderr
    assert "fm fold 2/2: epoch 2/2, loss" in r.stderr and "samples/s" in r.stderr, r.stderr
    metrics = json.loads((out / "metrics.json").read_text())
    fm = metrics["models"]["fm"]
    keys = [f["key"] for f in fm["figures"]]
    assert keys == ["fm/theta", "fm/ef"]
    for f in fm["figures"]:
        assert len(f["folds"]) == 2 and f["baseline"] > 0 and f["paper"] > 0
    assert fm["runs"][0]["epochs"] == 2 and fm["runs"][0]["wall_s"] > 0
    meta = json.loads((out / "fm.json").read_text())
    assert meta["problem"]["input_names"][:2] == ["theta0", "theta1"] and meta["problem"]["input_names"][-1] == "a6"
    assert meta["sources"][0]["blake3"] and meta["training"]["train"]["optimizer"]["kind"] == "adam"
    assert (out / "fm.safetensors").stat().st_size > 1000
    # A second model accumulates in metrics.json.
    r = train(run_cli, bags, "--bag", bags / "exp1", "--model", "im-mono", "--out", out)
    assert r.returncode == 0, r.stderr
    assert set(json.loads((out / "metrics.json").read_text())["models"]) == {"fm", "im-mono"}


def test_learning_curve_ends_at_the_reported_figure(run_cli, bags):
    out = bags / "curve"
    r = train(run_cli, bags, "--bag", bags / "exp1", "--model", "fm", "--epochs", "5", "--eval-every", "2",
              "--lr-schedule", "cosine:0.1", "--out", out)
    assert r.returncode == 0, r.stderr
    fm = json.loads((out / "metrics.json").read_text())["models"]["fm"]
    assert fm["options"]["lr_schedule"] == "cosine:0.1"
    for fold, run in enumerate(fm["runs"]):
        curve = run["curve"]
        assert [p["epoch"] for p in curve] == [2, 4, 5]
        assert all(0 < a["wall_s"] <= b["wall_s"] for a, b in zip(curve, curve[1:]))
        # The last point is the finished model: the same held-out MAE as the fold's figure.
        for head, figure in enumerate(fm["figures"]):
            assert curve[-1]["mae"][head] == pytest.approx(figure["folds"][fold]["mae"], rel=1e-9)
    assert "held-out MAE" in r.stderr


@pytest.mark.parametrize("args,message", [
    (["--model", "nope"], "unknown model \"nope\""),
    (["--profile", "huge"], "unknown profile"),
    (["--folds", "1"], "--folds must be at least 2"),
    (["--epochs", "0"], "--epochs must be at least 1"),
    (["--experiment", "exp2"], "holds exp1 data"),
    (["--model", "im-pre", "--bag-exp2"], "exp1 only"),
    (["--fm-hidden", "0"], "hidden layer widths must be positive"),
    (["--action", "wished"], "unknown action source"),
    (["--lr-schedule", "linear"], "unknown learning-rate schedule"),
    (["--eval-every", "0"], "--eval-every must be at least 1"),
])
def test_bad_train_input_is_refused(run_cli, bags, args, message):
    bag = bags / "exp1"
    if "--bag-exp2" in args:
        args = [a for a in args if a != "--bag-exp2"]
        bag = bags / "exp2"
    r = train(run_cli, bags, "--bag", bag, "--out", bags / "bad", *args)
    assert r.returncode == 1, r.stdout
    assert message in r.stderr, r.stderr


def test_missing_bag_and_mixed_experiments_are_refused(run_cli, bags):
    r = train(run_cli, bags, "--bag", bags / "nowhere", "--out", bags / "bad")
    assert r.returncode == 1 and "nowhere" in r.stderr
    r = train(run_cli, bags, "--bag", bags / "exp1", "--bag", bags / "exp2", "--out", bags / "bad")
    assert r.returncode == 1 and "holds exp2" in r.stderr, r.stderr


def test_rollout_writes_curves_and_refuses_bad_input(run_cli, bags):
    out = bags / "models_r"
    assert train(run_cli, bags, "--bag", bags / "exp1", "--model", "fm", "--out", out).returncode == 0
    r = run_cli("rollout", "--model", out, "--bag", bags / "exp1", "--trajectories", "100", "--cache", bags / "cache")
    assert r.returncode == 0, r.stderr
    sim = json.loads((out / "mental_simulation.json").read_text())
    assert sim["trajectories"] == 100 and [c["group"] for c in sim["curves"]] == ["theta", "ef"]
    assert (out / "mental_simulation.png").read_bytes()[1:4] == b"PNG"
    r = run_cli("rollout", "--model", out, "--bag", bags / "exp1", "--trajectories", "1000", "--cache", bags / "cache")
    assert r.returncode == 1 and "only 149 windows" in r.stderr, r.stderr
    r = run_cli("rollout", "--model", out, "--bag", bags / "exp2", "--cache", bags / "cache")
    assert r.returncode == 1 and "holds exp2" in r.stderr, r.stderr
    (out / "fm.json").write_text("{broken")
    r = run_cli("rollout", "--model", out, "--bag", bags / "exp1", "--cache", bags / "cache")
    assert r.returncode == 1 and "fm.json" in r.stderr and "not a model description" in r.stderr, r.stderr


def test_factored_auto_says_which_candidate_it_kept(run_cli, bags, tmp_path):
    # exp1's true graph as a claims file: a_i moves theta_i, a0..a5 move the effector.
    states = [f"theta{i}" for i in range(7)] + ["ef_x", "ef_y", "ef_z"]
    actions = [f"a{i}" for i in range(7)]
    drives = [[s == f"theta{a}" or (s.startswith("ef_") and a < 6) for s in states] for a in range(7)]
    claims = tmp_path / "claims.json"
    claims.write_text(json.dumps([{"method": "truth", "context": "all", "action_names": actions,
                                   "state_names": states, "drives": drives}]))
    out = tmp_path / "factored"
    r = train(run_cli, bags, "--bag", bags / "exp1", "--model", "fm-factored", "--graph", claims,
              "--factored-hidden", "16", "--max-folds", "1", "--out", out)
    assert r.returncode == 0, r.stderr
    runs = json.loads((out / "metrics.json").read_text())["models"]["fm-factored"]["runs"]
    labels = [run["label"] for run in runs]
    # The full FM is fitted on the fit rows first, as every head's yardstick.
    assert labels[0] == "fm-factored full-fm [validation] fold 1/2", labels
    candidates = [run for run in runs if run.get("selection")]
    assert [run["label"] for run in candidates] == [
        "fm-factored theta [none] fold 1/2", "fm-factored theta [determined] fold 1/2",
        "fm-factored ef [none] fold 1/2", "fm-factored ef [upstream] fold 1/2"]
    kept_full_fm = False
    for head in (candidates[:2], candidates[2:]):
        best = min(head, key=lambda run: run["selection"]["validation_mae"])
        comparison = best["selection"]["against_full_fm"]
        assert f"{best['label']}: 2 epochs on" in r.stderr, r.stderr
        kept = [run for run in head if run["selection"]["chosen"]]
        if comparison["candidate_better"]:
            assert kept == [best]
            assert comparison["difference"] < -2 * comparison["standard_error"]
        else:
            assert kept == []
            kept_full_fm = True
    # A head that keeps the full FM's gets the full FM refitted on all training rows.
    assert ("fm-factored full-fm fold 1/2" in labels) == kept_full_fm, labels
    assert ("the full FM's head is kept" in r.stderr) == kept_full_fm, r.stderr
    r = train(run_cli, bags, "--bag", bags / "exp1", "--model", "fm-factored", "--graph", claims,
              "--factored-auxiliary", "sometimes", "--out", out)
    assert r.returncode != 0 and "none, upstream, determined, auto" in r.stderr, r.stderr
