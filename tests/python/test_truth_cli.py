"""`causal-arm intervene` and `explain --truth` from the command line: the simulator's truth
files, claims scored against them, and clear errors with a non-zero exit for bad input
(no states, a truth of the other experiment, a file that is no truth)."""

import csv
import json

import pytest

from conftest import bag_and_forward_model


@pytest.fixture(scope="module")
def runs(run_cli, tmp_path_factory):
    d = tmp_path_factory.mktemp("truth_cli")
    bag_and_forward_model(run_cli, d, ["exp1", "--steps", "1500", "--seed", "5"],
                          ["--epochs", "3", "--folds", "2", "--max-folds", "1", "--fm-hidden", "32"])
    r = run_cli("generate", "exp2", "--episodes", "2", "--seed", "5", "--out", d / "exp2")
    assert r.returncode == 0, r.stderr
    return d


def test_intervene_writes_a_truth_that_scores_claims(run_cli, runs):
    out = runs / "truth1"
    r = run_cli("intervene", "exp1", "--bag", runs / "bag", "--states", "200", "--out", out)
    assert r.returncode == 0, r.stderr
    assert "noise floor of an identical replay: 0e0" in r.stdout
    truth = json.loads((out / "truth.json").read_text())
    one_step = truth["matrices"][0]
    assert (one_step["context"], one_step["horizon"], one_step["states"]) == ("all", 1, 200)
    names = truth["state_names"]
    for j, action in enumerate(truth["action_names"]):
        for k in range(7):
            active = one_step["active_fraction"][j][k]
            assert (active > 0) == (j == k), f"{action} -> {names[k]}: {active}"
    rows = list(csv.DictReader(open(out / "truth.csv")))
    assert len(rows) == 7 * 10 and {r["edge"] for r in rows} <= {"present", "absent", "rare"}
    assert (out / "truth_heatmap.png").stat().st_size > 1000

    r = run_cli("explain", "--model", runs / "models", "--bag", runs / "bag", "--method", "cai",
                "--samples", "100", "--truth", out, "--out", runs / "cai", "--cache", runs / "cache")
    assert r.returncode == 0, r.stderr
    assert "scored against" in r.stdout and "cai/err" in r.stdout
    scores = json.loads((runs / "cai" / "scores.json").read_text())
    overall = next(s for s in scores if s["block"] == "all" and s["context"] == "all")
    assert overall["scores"]["scored"] == 70
    assert 0.0 <= overall["scores"]["auroc"] <= 1.0


@pytest.mark.parametrize("args,message", [
    (["exp1", "--states", "0"], "--states must be at least 1"),
    (["exp2", "--states", "10"], "holds exp1 data"),
    (["exp1", "--states", "100000"], "asks for more"),
])
def test_bad_intervene_input_is_refused(run_cli, runs, args, message):
    r = run_cli("intervene", *args, "--bag", runs / "bag", "--out", runs / "bad")
    assert r.returncode != 0
    assert message in r.stderr, r.stderr


def test_a_truth_of_the_other_experiment_or_no_truth_is_refused(run_cli, runs):
    other = runs / "truth2"
    r = run_cli("intervene", "exp2", "--bag", runs / "exp2", "--states", "50", "--out", other)
    assert r.returncode == 0, r.stderr
    r = run_cli("explain", "--model", runs / "models", "--bag", runs / "bag", "--method", "cai",
                "--samples", "50", "--truth", other, "--out", runs / "cai2", "--cache", runs / "cache")
    assert r.returncode != 0
    assert "the truth (exp2) has actions" in r.stderr, r.stderr
    bogus = runs / "bogus.json"
    bogus.write_text('{"format": "something else"}')
    r = run_cli("explain", "--model", runs / "models", "--bag", runs / "bag", "--method", "cai",
                "--truth", bogus, "--cache", runs / "cache")
    assert r.returncode != 0
    assert "not a truth file" in r.stderr, r.stderr
