"""`causal-arm explain --method cai --horizon K`: CAI through the chained forward model,
scored per horizon against `causal-arm intervene --horizon K`, with the magnet → cube-height
line, and clear errors (non-zero exit) for a horizon out of 1..10, a horizon the truth does
not have, and a method other than CAI."""

import json

import pytest

from conftest import bag_and_forward_model


@pytest.fixture(scope="module")
def runs(run_cli, tmp_path_factory):
    d = tmp_path_factory.mktemp("multistep_cli")
    bag_and_forward_model(run_cli, d,
                          ["exp2", "--episodes", "2", "--seed", "5", "--move-while-switching"],
                          ["--epochs", "3", "--folds", "2", "--max-folds", "1", "--fm-hidden", "32"])
    for horizon in (1, 3):
        r = run_cli("intervene", "exp2", "--bag", d / "bag", "--states", "60",
                    "--horizon", horizon, "--out", d / f"truth_h{horizon}", timeout=300)
        assert r.returncode == 0, r.stderr
    return d


def explain(run_cli, runs, horizon, truth, out, *extra):
    return run_cli("explain", "--model", runs / "models", "--bag", runs / "bag",
                   "--method", "cai", "--samples", "60", "--resamples", "16",
                   "--horizon", horizon, "--truth", runs / truth, "--out", runs / out,
                   "--cache", runs / "cache", *extra, timeout=300)


def test_every_horizon_is_scored_against_the_truth_at_that_horizon(run_cli, runs):
    r = explain(run_cli, runs, 3, "truth_h3", "ms3")
    assert r.returncode == 0, r.stderr
    assert "cai through the FM chained 3 steps" in r.stdout, r.stdout
    assert "scored against" in r.stdout
    # The per-horizon table: one line per horizon over all states and pairs.
    for method in ("cai+data", "cai/err", "data"):
        table = [line.split() for line in r.stdout.splitlines() if line.startswith(method + " ")]
        assert sorted(int(cols[3]) for cols in table) == [1, 2, 3], (method, r.stdout)
    counts = [line for line in r.stdout.splitlines() if line.startswith("h=")]
    assert len(counts) == 3 and all("cai+data:" in line and "undecided" in line
                                    for line in counts), r.stdout
    magnet = [line for line in r.stdout.splitlines() if line.startswith("a_mgt → o_z")]
    assert len(magnet) == 1 and "h=1 " in magnet[0] and "h=3 " in magnet[0], r.stdout

    result = json.loads((runs / "ms3" / "multistep.json").read_text())
    assert result["horizon"] == 3 and result["observations"] == 60
    assert [h["horizon"] for h in result["horizons"]] == [1, 2, 3]
    truth = json.loads((runs / "truth_h3" / "truth.json").read_text())
    for h in result["horizons"]:
        contexts = [c["context"] for c in h["claims"]]
        assert contexts[0] == "all" and len(contexts) == 7
        assert all(c["horizon"] == h["horizon"] for c in h["claims"])
        # Three-valued verdicts per horizon, and the data's own test beside them.
        default, data = h["default"], h["data"]
        assert (default["method"], data["method"]) == ("cai+data", "data")
        assert default["horizon"] == data["horizon"] == h["horizon"]
        verdicts = {d["verdict"] for row in default["decisions"] for d in row}
        assert verdicts <= {"drives", "does-not", "undecided"}
        cai = h["claims"][0]
        for a, row in enumerate(default["decisions"]):
            for k, d in enumerate(row):
                assert default["drives"][a][k] == (d["verdict"] == "drives")
                if h["horizon"] > 1:
                    # Beyond one step only the chained model claims; never more than CAI.
                    assert not d["verdict"] == "drives" or cai["drives"][a][k]
                    assert d["verdict"] != "does-not" or not data["drives"][a][k]
        overall = next(s for s in h["scores"] if s["context"] == "all" and s["block"] == "all")
        assert overall["horizon"] == h["horizon"]
        s = overall["scores"]
        assert s["scored"] + s["not_scored"] == 8 * 23
        assert s["auroc"] is None or 0.0 <= s["auroc"] <= 1.0
        assert {b["block"] for b in h["scores"] if b["context"] == "all"} == \
            {"all", "theta", "ef", "object", "magnet"}
        # Scored against the truth's matrix at the same horizon: the present edges agree.
        matrix = next(m for m in truth["matrices"]
                      if m["context"] == "all" and m["horizon"] == h["horizon"])
        present = sum(f >= truth["plan"]["min_fraction"] for row in matrix["active_fraction"]
                      for f in row)
        assert s["true_positives"] + s["false_negatives"] == present
    for figure in ("multistep_scores.png", "multistep_a_mgt_o_z.png"):
        assert (runs / "ms3" / figure).stat().st_size > 1000


@pytest.mark.parametrize("horizon,truth,message", [
    (0, "truth_h3", "the horizon must be 1 to 10 steps"),
    (11, "truth_h3", "the horizon must be 1 to 10 steps"),
    (3, "truth_h1", "the truth has no matrices at horizon 3 (its horizons: 1)"),
])
def test_a_bad_horizon_is_refused(run_cli, runs, horizon, truth, message):
    r = explain(run_cli, runs, horizon, truth, "bad")
    assert r.returncode != 0
    assert message in r.stderr, r.stderr


def test_the_horizon_needs_cai(run_cli, runs):
    r = run_cli("explain", "--model", runs / "models", "--bag", runs / "bag", "--method", "deep",
                "--horizon", "2", "--cache", runs / "cache")
    assert r.returncode != 0
    assert "use it with --method cai" in r.stderr, r.stderr
