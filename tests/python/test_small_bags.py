"""Too little data is an answer, not an error: on a one-episode exp2 bag (499 transitions,
fewer than the data test's design needs) `causal-arm explain`, `causal-arm discover` and the
explainer node all answer, and the data test's edges are undecided with the reason and
how many transitions would do."""

import json
import os

import pytest

import ros_idl as idl
from conftest import bag_and_forward_model, node_process
from test_explainer_node import RelevanceV2, take_latched

DOMAIN = 47


@pytest.fixture(scope="module")
def one_episode(run_cli, tmp_path_factory):
    d = tmp_path_factory.mktemp("small")
    bag_and_forward_model(run_cli, d, ["exp2", "--profile", "quick", "--episodes", "1", "--seed", "11"],
                          ["--epochs", "10", "--folds", "2", "--max-folds", "1", "--fm-hidden", "32,32"])
    return d


def too_few(reason: str) -> bool:
    return "the data test needs at least" in reason and "the data has 499" in reason


def test_discover_answers_with_undecided_edges_and_the_rows_it_needs(one_episode, run_cli):
    d = one_episode
    r = run_cli("discover", "--bag", d / "bag", "--cache", d / "cache", "--out", d / "discover", timeout=300)
    assert r.returncode == 0, r.stderr
    claims = json.loads((d / "discover" / "claims.json").read_text())
    data = claims[0]
    assert data["method"] == "data" and data["rule"].startswith("data: not run"), data["rule"]
    decisions = [x for row in data["decisions"] for x in row]
    assert not any(x["verdict"] == "drives" for x in decisions)
    undecided = [x for x in decisions if x["verdict"] == "undecided"]
    assert undecided and all(too_few(x["reason"]) for x in undecided), undecided[:2]
    assert all(x["to_decide"].split()[0].isdigit() for x in undecided)
    # The linear anchors' designs are small enough for 499 transitions: they ran.
    assert [c["method"] for c in claims[1:]] == ["granger", "granger-x"]
    assert all(c["rule"].startswith("drives when") for c in claims[1:])


def test_explain_answers_and_writes_its_report(one_episode, run_cli):
    d = one_episode
    r = run_cli("explain", "--model", d / "models", "--bag", d / "bag", "--method", "kernel", "--samples", "40",
                "--no-pair-plots", "--cache", d / "cache", "--out", d / "kernel", timeout=300)
    assert r.returncode == 0, r.stderr
    report = json.loads((d / "kernel" / "relevance.json").read_text())
    decisions = [x for row in report["decisions"] for x in row]
    assert any(x["verdict"] == "undecided" and too_few(x["reason"]) for x in decisions), decisions[:3]
    assert "needs at least" in r.stdout or "needs at least" in r.stderr


def test_the_explainer_node_serves_on_a_one_episode_bag(one_episode, causal_arm_bin, private_netns):
    from cyclonedds.domain import DomainParticipant

    d = one_episode
    env = dict(os.environ, RMW_IMPLEMENTATION="rmw_cyclonedds_cpp", ROS_DOMAIN_ID=str(DOMAIN))
    params = ["-p", f"model_dir:={d / 'models'}", "-p", f"bag:={d / 'bag'}", "-p", f"cache:={d / 'cache'}",
              "-p", "samples:=20"]
    with node_process(causal_arm_bin.parent / "causal_arm_explainer", params, env) as node:
        participant = DomainParticipant(DOMAIN)
        client = idl.ServiceClient(participant, "/explainer/explain", idl.ExplainRequest, idl.ExplainReply)
        assert client.wait_for_server(timeout=120), node.log()[-3000:]
        msg = take_latched(participant, RelevanceV2)
        assert any(v == "undecided" and too_few(r) for v, r in zip(msg.verdict, msg.reason)), list(msg.reason)[:3]
        state = [0.0] * 23
        reply = client.call(idl.ExplainRequest(method="kernel", state=state, action=[0.0] * 8, rows=1), timeout=60)
        assert reply.success, reply.message
        assert node.poll() is None, node.log()[-3000:]
