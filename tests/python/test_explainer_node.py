"""`causal-arm explain` and the explainer node, checked from outside: the files it writes
(read with numpy), the latched /explainer/relevance report and the /explainer/explain
service as an independent ROS 2 peer (CycloneDDS Python, rmw_cyclonedds layout) sees them,
and bad input for both."""

import json
import os
import subprocess
import time

import numpy as np
import pytest

import ros_idl as idl
from conftest import bag_and_forward_model, node_process
from model_numpy import load_safetensors, numpy_predict

DOMAIN = 43


@pytest.fixture(scope="module")
def exp2(run_cli, tmp_path_factory):
    """A small exp2 bag, an FM trained on it and a deep explanation of it."""
    d = tmp_path_factory.mktemp("explainer")
    bag_and_forward_model(run_cli, d, ["exp2", "--profile", "quick", "--episodes", "4", "--seed", "3"],
                          ["--epochs", "30", "--folds", "2", "--max-folds", "1", "--fm-hidden", "64,64"])
    r = run_cli("explain", "--model", d / "models", "--bag", d / "bag", "--method", "deep", "--samples", "200",
                "--cache", d / "cache", "--out", d / "deep", timeout=300)
    assert r.returncode == 0, r.stderr
    return d, r


def test_cli_writes_every_file_and_the_colour_verdict(exp2):
    d, r = exp2
    out = d / "deep"
    for name in ["shap_values.safetensors", "explanation.json", "relevance.json", "relevance.csv",
                 "heatmap.png", "heatmap.svg", "pdp_grid.png", "pdp_grid.svg", "pdp/a_mgt__o_z.png", "pdp/a0__theta0.svg"]:
        assert (out / name).stat().st_size > 100, name
    assert (out / "heatmap.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert len(list((out / "pdp").glob("*.png"))) == 8 * 23
    assert "not affected by any action (removable from the state): o_R, o_G, o_B" in r.stdout
    assert f"wrote {out / 'relevance.json'}" in r.stderr

    report = json.loads((out / "relevance.json").read_text())
    verdicts = {v["name"]: v for v in report["states"]}
    for colour in ["o_R", "o_G", "o_B"]:
        assert not verdicts[colour]["affected"] and verdicts[colour]["scale"] == 0.0
    for j in range(7):
        assert verdicts[f"theta{j}"]["strongest_action"] == f"a{j}"
    csv = (out / "relevance.csv").read_text().splitlines()
    assert csv[0].startswith("state,verdict,score")
    assert len(csv) == 24

    t, meta = load_safetensors(out / "shap_values.safetensors", with_metadata=True)
    assert t["values"].shape == (200, 31, 23)
    assert json.loads(meta["input_names"])[-1] == "a_mgt" and meta["method"] == "deep"
    # The explained outputs are the model files' forward pass; attributions sum to
    # f(x) − mean f(background) (efficiency), relative to the spread of the outputs.
    f_x = numpy_predict(d / "models", "fm", t["observations"])
    f_bg = numpy_predict(d / "models", "fm", t["background"])
    scale = np.abs(f_x).max(axis=0) + 1e-9
    assert np.all(np.abs(t["outputs"] - f_x) <= 1e-5 * scale)
    gap = t["values"].sum(axis=1) - (f_x - f_bg.mean(axis=0))
    assert np.all(np.abs(gap) <= 1e-5 * scale), np.abs(gap / scale).max()
    summary = json.loads((out / "explanation.json").read_text())
    assert summary["observations"] == 200 and summary["background"] == 100 and summary["seconds"] > 0


@pytest.mark.parametrize("args,message", [
    (["--method", "lime"], "unknown SHAP method \"lime\""),
    (["--samples", "0"], "samples must be at least 1"),
    (["--background-kind", "kmeans"], "equal weights"),
    (["--samples", "100000"], "transitions"),
    (["--threshold", "0"], "--threshold must be a positive number, got 0"),
])
def test_cli_bad_options_are_clear_errors(exp2, run_cli, args, message):
    d, _ = exp2
    r = run_cli("explain", "--model", d / "models", "--bag", d / "bag", "--cache", d / "cache",
                "--out", d / "bad", *args)
    assert r.returncode != 0
    assert message in r.stderr, r.stderr
    assert not (d / "bad").exists()


def test_cli_refuses_a_bag_of_the_other_experiment_and_a_missing_model(exp2, run_cli, tmp_path):
    d, _ = exp2
    r = run_cli("generate", "exp1", "--profile", "quick", "--steps", "300", "--out", tmp_path / "exp1")
    assert r.returncode == 0, r.stderr
    r = run_cli("explain", "--model", d / "models", "--bag", tmp_path / "exp1", "--out", tmp_path / "x")
    assert r.returncode != 0 and "expected exp2" in r.stderr, r.stderr
    r = run_cli("explain", "--model", tmp_path / "nowhere", "--bag", d / "bag", "--out", tmp_path / "x")
    assert r.returncode != 0 and "fm.json" in r.stderr, r.stderr


@pytest.fixture(scope="module")
def explainer_node(exp2, causal_arm_bin, private_netns_module):
    d, _ = exp2
    env = dict(os.environ, RMW_IMPLEMENTATION="rmw_cyclonedds_cpp", ROS_DOMAIN_ID=str(DOMAIN))
    params = ["-p", f"model_dir:={d / 'models'}", "-p", f"bag:={d / 'bag'}", "-p", f"cache:={d / 'cache'}"]
    with node_process(causal_arm_bin.parent / "causal_arm_explainer", params, env) as proc:
        yield proc


@pytest.fixture(scope="module")
def participant(explainer_node):
    from cyclonedds.domain import DomainParticipant

    return DomainParticipant(DOMAIN)


@pytest.fixture(scope="module")
def client(participant, explainer_node):
    c = idl.ServiceClient(participant, "/explainer/explain", idl.ExplainRequest, idl.ExplainReply)
    assert c.wait_for_server(), "no /explainer/explain server matched"
    return c


def test_relevance_report_is_latched_and_equals_the_cli_report(exp2, participant, client):
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic

    d, _ = exp2
    # Joined late (after the node published): transient-local still delivers the report.
    reader = DataReader(participant, Topic(participant, "rt/explainer/relevance", idl.Relevance), qos=idl.latched_qos())
    deadline = time.monotonic() + 20
    samples = []
    while not samples and time.monotonic() < deadline:
        samples = reader.take(N=4)
        time.sleep(0.05)
    assert samples, "no latched /explainer/relevance report"
    msg = samples[0]
    cli = json.loads((d / "deep" / "relevance.json").read_text())
    assert (msg.experiment, msg.method, msg.observations, msg.background) == ("exp2", "deep", 200, 100)
    assert list(msg.action_names) == cli["action_names"] and list(msg.state_names) == cli["state_names"]
    # Same seed, data and method as the CLI run: the same numbers.
    np.testing.assert_allclose(np.array(msg.mean_abs_shap).reshape(8, 23), np.array(cli["mean_abs_shap"]), rtol=1e-9, atol=1e-15)
    assert list(msg.affected) == [v["affected"] for v in cli["states"]]
    assert msg.affected[6:9] == [False, False, False]  # colour
    assert msg.rule == cli["rule"] and "one-step change" in msg.rule and msg.threshold == cli["threshold"]


def test_explain_service_attributions_are_efficient_against_numpy(exp2, client):
    d, _ = exp2
    t = load_safetensors(d / "deep" / "shap_values.safetensors")
    rows = t["observations"][:6]
    for method in ["deep", "kernel"]:
        reply = client.call(idl.ExplainRequest(method=method, state=rows[:, :23].ravel().tolist(),
                                               action=rows[:, 23:].ravel().tolist(), rows=6), timeout=60)
        assert reply.success, reply.message
        assert reply.rows == 6 and len(reply.input_names) == 31 and reply.output_names[2] == "o_z_next"
        phi = np.array(reply.attributions).reshape(6, 23, 31)  # rows × outputs × inputs
        # Efficiency without knowing the node's background: differences between two rows of one
        # request cancel E f(background), so Σφ(x) − Σφ(x') = f(x) − f(x') from numpy alone.
        f = numpy_predict(d / "models", "fm", rows)
        sums = phi.sum(axis=2)
        scale = np.abs(f).max(axis=0) + 1e-9
        gap = (sums - sums[0]) - (f - f[0])
        assert np.all(np.abs(gap) <= 1e-5 * scale), (method, np.abs(gap / scale).max())
        # Colour never moves: no action gets any of it.
        assert np.all(np.abs(phi[:, 6:9, 23:]) < 1e-9)


@pytest.mark.parametrize("change,message", [
    ({"method": "lime"}, "unknown SHAP method"),
    ({"rows": 0}, "rows must be at least 1"),
    ({"rows": 2}, "state has 23 values, expected rows × 23 = 46"),
    ({"action": [0.0] * 7}, "action has 7 values"),
    ({"state": [float("nan")] + [0.0] * 22}, "state[0] (row 0, column 0) is NaN"),
    ({"action": [0.0] * 7 + [float("inf")]}, "action[7] (row 0, column 7) is inf"),
    ({"rows": 4_000_000_000}, "exceeds the deep SHAP limit"),
    ({"background": 100000}, "exceeds the"),
    ({"method": "kernel", "rows": 51}, "exceeds the kernel SHAP limit of 50"),
    ({"state": [], "action": [], "rows": 1}, "state has 0 values"),
])
def test_bad_requests_get_error_replies_and_the_node_keeps_serving(client, explainer_node, change, message):
    request = dict(method="deep", state=[0.1] * 23, action=[0.0] * 8, rows=1, background=0)
    request.update(change)
    reply = client.call(idl.ExplainRequest(**request))
    assert not reply.success and message in reply.message, reply.message
    assert reply.rows == 0 and not reply.attributions
    ok = client.call(idl.ExplainRequest(method="deep", state=[0.1] * 23, action=[0.0] * 8, rows=1))
    assert ok.success, ok.message
    assert explainer_node.poll() is None


def test_node_refuses_missing_parameters_and_the_wrong_experiment(causal_arm_bin, exp2, run_cli, tmp_path, private_netns):
    d, _ = exp2
    binary = causal_arm_bin.parent / "causal_arm_explainer"
    env = dict(os.environ, ROS_DOMAIN_ID=str(DOMAIN + 1))
    r = subprocess.run([str(binary), "--ros-args", "-p", f"model_dir:={d / 'models'}"], env=env,
                       capture_output=True, text=True, timeout=60)
    assert r.returncode != 0 and "parameters model_dir and bag are required" in r.stderr, r.stderr
    r = run_cli("generate", "exp1", "--profile", "quick", "--steps", "300", "--out", tmp_path / "exp1")
    assert r.returncode == 0, r.stderr
    r = subprocess.run([str(binary), "--ros-args", "-p", f"model_dir:={d / 'models'}", "-p", f"bag:={tmp_path / 'exp1'}"],
                       env=env, capture_output=True, text=True, timeout=60)
    assert r.returncode != 0 and "expected exp2" in r.stderr, r.stderr
