"""`causal-arm discover` and `causal-arm score` from the command line: three-valued verdicts
straight from a bag's transitions, scored against the simulator's truth beside the linear
Granger anchors; the exported transitions as numpy reads them; and clear errors with a
non-zero exit for bad input (a truth of the other experiment, a claims file that is none,
a budget-bench grid cell of 0 steps)."""

import json
import subprocess
import sys

import numpy as np
import pytest
from safetensors.numpy import load_file


@pytest.fixture(scope="module")
def runs(run_cli, tmp_path_factory):
    d = tmp_path_factory.mktemp("discover_cli")
    for args in (["exp1", "--steps", "4000", "--seed", "2", "--out", d / "exp1"],
                 ["exp2", "--episodes", "2", "--seed", "2", "--out", d / "exp2"]):
        r = run_cli("generate", *args)
        assert r.returncode == 0, r.stderr
    r = run_cli("intervene", "exp1", "--bag", d / "exp1", "--states", "300", "--out", d / "truth1")
    assert r.returncode == 0, r.stderr
    r = run_cli("intervene", "exp2", "--bag", d / "exp2", "--states", "100", "--out", d / "truth2")
    assert r.returncode == 0, r.stderr
    return d


def test_discover_decides_three_ways_and_is_right_where_it_decides(run_cli, runs):
    out = runs / "discover"
    r = run_cli("discover", "--bag", runs / "exp1", "--truth", runs / "truth1", "--out", out,
                "--export", runs / "t.safetensors")
    assert r.returncode == 0, r.stderr
    claims = json.loads((out / "claims.json").read_text())
    assert [c["method"] for c in claims] == ["data", "granger", "granger-x"]
    data = claims[0]
    verdicts = np.array([[d["verdict"] for d in row] for row in data["decisions"]])
    assert set(verdicts.ravel()) <= {"drives", "does-not", "undecided"}
    assert np.array_equal(verdicts == "drives", np.array(data["drives"]))
    # Every joint action drives its own angle; no other angle: the data denies those.
    for j in range(7):
        for k in range(7):
            assert verdicts[j, k] == ("drives" if j == k else "does-not"), (j, k)
    undecided = [d for row in data["decisions"] for d in row if d["verdict"] == "undecided"]
    assert all(d["reason"] and d["to_decide"] for d in undecided)
    counts = {v: int((verdicts == v).sum()) for v in ("drives", "does-not", "undecided")}
    assert f"verdicts (data): {counts['drives']} drives, {counts['does-not']} does not, {counts['undecided']} undecided" in r.stdout
    rows = json.loads((out / "scores.json").read_text())
    headline = {r["method"]: r["scores"] for r in rows if r["context"] == "all" and r["block"] == "all"}
    assert headline["data"]["precision"] == 1.0 and headline["data"]["false_denials"] == 0
    assert headline["data"]["undecided"] == counts["undecided"]
    # The plain linear test misses the effector edges whose gain depends on the pose.
    assert headline["data"]["recall"] > headline["granger"]["recall"]

    # The exported transitions are the dataset: next − now is each joint's action.
    t = load_file(runs / "t.safetensors")
    assert t["states"].shape == (3999, 10) and t["actions"].shape == (3999, 7)
    np.testing.assert_allclose(t["next_states"][:, :7] - t["states"][:, :7], t["actions"], atol=1e-6)


def test_score_scores_any_tools_claims_by_the_projects_scorer(run_cli, runs):
    claims = runs / "discover" / "claims.json"
    r = run_cli("score", "--claims", claims, "--truth", runs / "truth1", "--out", runs / "s.json")
    assert r.returncode == 0, r.stderr
    mine = json.loads((runs / "s.json").read_text())
    theirs = json.loads((runs / "discover" / "scores.json").read_text())
    assert mine == theirs


def test_a_truth_of_the_other_experiment_and_a_bad_claims_file_are_refused(run_cli, runs):
    r = run_cli("discover", "--bag", runs / "exp1", "--truth", runs / "truth2", "--out", runs / "x")
    assert r.returncode != 0 and "the truth (exp2)" in r.stderr, r.stderr
    assert not (runs / "x" / "claims.json").exists()
    bad = runs / "bad.json"
    bad.write_text('{"method": "x"}')
    r = run_cli("score", "--claims", bad, "--truth", runs / "truth1")
    assert r.returncode != 0 and f"{bad}: not a JSON list of claim sets" in r.stderr, r.stderr
    r = run_cli("score", "--claims", runs / "discover" / "claims.json", "--truth", runs / "truth2")
    assert r.returncode != 0 and "the truth (exp2)" in r.stderr, r.stderr


@pytest.mark.parametrize("cell, problem", [
    ("exp1:0", "expected exp1:<steps> or exp2:<steps> with steps > 0"),
    ("exp3:5000", "expected exp1:<steps> or exp2:<steps>"),
    ("exp2:750", "steps must be a multiple of 500"),
])
def test_the_budget_bench_refuses_a_bad_grid_cell(repo_root, cell, problem):
    r = subprocess.run([sys.executable, repo_root / "tests" / "bench" / "causal_budget.py",
                        "--cells", cell], capture_output=True, text=True, timeout=60)
    assert r.returncode != 0 and f"grid cell {cell!r}" in r.stderr and problem in r.stderr, r.stderr
