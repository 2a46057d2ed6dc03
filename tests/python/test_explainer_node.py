"""`causal-arm explain` and the explainer node, checked from outside: the files it writes
(read with numpy), the latched /explainer/relevance report and the /explainer/explain
service as independent ROS 2 peers (CycloneDDS Python, rmw_cyclonedds layout; real rclpy on
rmw_fastrtps_cpp) see them, and bad input for both."""

import json
import os
import subprocess
import time
from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np
import pytest
from cyclonedds.idl import IdlStruct
from cyclonedds.idl import types as t

import ros_idl as idl
from conftest import bag_and_forward_model, node_process
from model_numpy import load_safetensors, numpy_predict
from rclpy_peer import DISTROS

DOMAIN = 43
# Observations of the node's report (Kernel SHAP and CAI): a few seconds on this bag.
NODE_SAMPLES = 40


@dataclass
class RelevanceV2(IdlStruct, typename="causal_arm_msgs::msg::dds_::Relevance_"):
    """msg/Relevance.msg with the appended calibrated and three-valued verdicts
    (ros_idl.Relevance is the layout before them: an old reader)."""

    header: idl.Header = field(default_factory=idl.Header)
    experiment: str = ""
    method: str = ""
    observations: t.uint32 = 0
    background: t.uint32 = 0
    action_names: t.sequence[str] = field(default_factory=list)
    state_names: t.sequence[str] = field(default_factory=list)
    mean_abs_shap: t.sequence[t.float64] = field(default_factory=list)
    state_scale: t.sequence[t.float64] = field(default_factory=list)
    affected: t.sequence[bool] = field(default_factory=list)
    threshold: t.float64 = 0.0
    rule: str = ""
    decision_method: str = ""
    drives: t.sequence[bool] = field(default_factory=list)
    score: t.sequence[t.float64] = field(default_factory=list)
    interval_lower: t.sequence[t.float64] = field(default_factory=list)
    interval_upper: t.sequence[t.float64] = field(default_factory=list)
    decision_rule: str = ""
    verdict: t.sequence[str] = field(default_factory=list)
    reason: t.sequence[str] = field(default_factory=list)
    to_decide: t.sequence[str] = field(default_factory=list)


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
    # The verdicts are the run's default claims (the data test, then the model's calibrated
    # evidence), as claims.json's first, three-valued.
    assert report["decision_method"] == "deep+cai+data"
    claims = json.loads((out / "claims.json").read_text())
    assert claims[0]["method"] == "deep+cai+data" and claims[0]["context"] == "all"
    assert report["decisions"] == claims[0]["decisions"]
    assert report["drives"] == claims[0]["drives"] and report["interval"] == claims[0]["interval"]
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
    (["--method", "kernel", "--kernel-samples", "1"], "nsamples 1 is fewer than the model's"),
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
def kernel_cli(exp2, run_cli):
    """The CLI's report with the node's defaults (Kernel SHAP ∪ CAI) on NODE_SAMPLES observations."""
    d, _ = exp2
    r = run_cli("explain", "--model", d / "models", "--bag", d / "bag", "--method", "kernel",
                "--samples", str(NODE_SAMPLES), "--no-pair-plots", "--cache", d / "cache", "--out", d / "kernel",
                timeout=300)
    assert r.returncode == 0, r.stderr
    return json.loads((d / "kernel" / "relevance.json").read_text())


@pytest.fixture(scope="module")
def explainer_node(exp2, causal_arm_bin, private_netns_module):
    d, _ = exp2
    env = dict(os.environ, RMW_IMPLEMENTATION="rmw_cyclonedds_cpp", ROS_DOMAIN_ID=str(DOMAIN))
    params = ["-p", f"model_dir:={d / 'models'}", "-p", f"bag:={d / 'bag'}", "-p", f"cache:={d / 'cache'}",
              "-p", f"samples:={NODE_SAMPLES}"]
    with node_process(causal_arm_bin.parent / "causal_arm_explainer", params, env) as proc:
        yield proc


@pytest.fixture(scope="module")
def participant(explainer_node):
    from cyclonedds.domain import DomainParticipant

    return DomainParticipant(DOMAIN)


@pytest.fixture(scope="module")
def client(participant, explainer_node):
    c = idl.ServiceClient(participant, "/explainer/explain", idl.ExplainRequest, idl.ExplainReply)
    # The node serves once its report is made (Kernel SHAP and CAI: seconds on this bag).
    assert c.wait_for_server(timeout=120), "no /explainer/explain server matched"
    return c


def take_latched(participant, idl_type, timeout=20.0):
    """The latched /explainer/relevance report, read by a reader of `idl_type` that joins
    after the node published (transient-local still delivers it)."""
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic

    reader = DataReader(participant, Topic(participant, "rt/explainer/relevance", idl_type), qos=idl.latched_qos())
    deadline = time.monotonic() + timeout
    samples = []
    while not samples and time.monotonic() < deadline:
        samples = reader.take(N=4)
        time.sleep(0.05)
    assert samples, "no latched /explainer/relevance report"
    return samples[0]


def check_verdicts(msg):
    """What must hold of the node's calibrated report on this bag: shapes, affected = some
    action drives the feature, drives ⇔ score ≥ 1 (score = the deciding evidence over its
    threshold), the score inside its interval (a CAI-decided score is the interval's lower
    end), colour never driven, each joint's action driving its own angle with an interval
    wholly above every other action's on that angle, and a_mgt's strongest edge on mgt.
    Returns the verdicts as an action × state matrix.

    Off-diagonal a_i → θ_j edges are claimed on this bag and are not asserted absent: the
    quick FM (30 epochs on 4 episodes) leaks a little of every joint action into every angle,
    and today's SHAP rule (0.01 × the change's std) claims that leak (scores 1–6 against
    60–110 on the diagonal), and CAI claims a_mgt → θ (the quick FM's angle predictions move
    with the magnet command by more than its error on them)."""
    na, ns = len(msg.action_names), len(msg.state_names)
    drives = np.array(msg.drives, dtype=bool).reshape(na, ns)
    score = np.array(msg.score).reshape(na, ns)
    lower, upper = np.array(msg.interval_lower).reshape(na, ns), np.array(msg.interval_upper).reshape(na, ns)
    assert list(msg.affected) == drives.any(axis=0).tolist()
    assert np.array_equal(drives, score >= 1.0), "a verdict disagrees with its score"
    assert np.all(lower <= score + 1e-12) and np.all(score <= upper + 1e-12), "a score outside its interval"
    state = {s: i for i, s in enumerate(msg.state_names)}
    for colour in ["o_R", "o_G", "o_B"]:
        assert not drives[:, state[colour]].any() and not msg.affected[state[colour]], f"{colour} driven"
    for j in range(7):
        k = state[f"theta{j}"]
        others = [a for a in range(na) if a != j]
        assert drives[j, k], f"a{j} does not drive theta{j}"
        assert lower[j, k] > upper[others, k].max(), (j, lower[j, k], upper[others, k])
    assert int(np.argmax(score[msg.action_names.index("a_mgt")])) == state["mgt"]
    return drives


def test_relevance_report_is_latched_calibrated_and_equals_the_cli_report(exp2, kernel_cli, participant, client):
    msg = take_latched(participant, RelevanceV2)
    cli = kernel_cli
    assert (msg.experiment, msg.method, msg.observations, msg.background) == ("exp2", "kernel", NODE_SAMPLES, 50)
    assert list(msg.action_names) == cli["action_names"] and list(msg.state_names) == cli["state_names"]
    # Same seed, data and settings as the CLI run: the same numbers.
    np.testing.assert_allclose(np.array(msg.mean_abs_shap).reshape(8, 23), np.array(cli["mean_abs_shap"]),
                               rtol=1e-9, atol=1e-15)
    assert msg.decision_method == cli["decision_method"] == "kernel+cai+data"
    decisions = [d for row in cli["decisions"] for d in row]
    assert list(msg.verdict) == [d["verdict"] for d in decisions]
    assert list(msg.reason) == [d["reason"] for d in decisions]
    assert list(msg.to_decide) == [d.get("to_decide", "") for d in decisions]
    assert set(msg.verdict) <= {"drives", "does-not", "undecided"}
    assert msg.decision_rule == cli["decision_rule"] and "CAI" in msg.decision_rule
    assert list(msg.drives) == [d for row in cli["drives"] for d in row]
    np.testing.assert_allclose(msg.score, np.ravel(cli["decision_score"]), rtol=1e-12)
    interval = np.array(cli["interval"])
    np.testing.assert_allclose(msg.interval_lower, interval[..., 0].ravel(), rtol=1e-12)
    np.testing.assert_allclose(msg.interval_upper, interval[..., 1].ravel(), rtol=1e-12)
    assert list(msg.affected) == [v["affected"] for v in cli["states"]]
    assert msg.rule == cli["rule"] and "one-step change" in msg.rule and msg.threshold == cli["threshold"]

    drives = check_verdicts(msg)
    # The default verdicts are not today's SHAP rule over all observations: that rule claims
    # the quick FM's leaks of every joint action into every angle; the data denies them.
    today = np.array(msg.mean_abs_shap).reshape(8, 23) >= msg.threshold * np.array(msg.state_scale)
    today &= np.array(msg.state_scale) > 0
    assert (today & ~drives).any(), "the default verdicts equal today's rule"
    theta = [list(msg.state_names).index(f"theta{j}") for j in range(7)]
    off_diagonal = ~np.eye(7, dtype=bool)
    assert not (drives[:7][:, theta] & off_diagonal).any(), "an a_i -> theta_j edge claimed"
    verdict = np.array(msg.verdict).reshape(8, 23)
    assert np.all(verdict[:7][:, theta][off_diagonal] == "does-not")
    # The checks can fail: a report with a verdict flipped, a colour driven or another action
    # outranking a joint's own on its angle is refused.
    state, action = list(msg.state_names).index, list(msg.action_names).index
    corruptions = [
        ("drives", action("a0") * 23 + state("theta0"), False),
        ("drives", action("a_mgt") * 23 + state("o_R"), True),
        ("interval_upper", action("a1") * 23 + state("theta0"), 1e6),
    ]
    for name, i, value in corruptions:
        bad = RelevanceV2(**{k: getattr(msg, k) for k in msg.__dataclass_fields__})
        setattr(bad, name, list(getattr(msg, name)))
        getattr(bad, name)[i] = value
        with pytest.raises(AssertionError):
            check_verdicts(bad)


def test_a_reader_of_the_old_layout_still_reads_the_report(participant, client):
    # ros_idl.Relevance is the message before the calibrated fields were appended.
    from cyclonedds.domain import DomainParticipant

    old = take_latched(DomainParticipant(DOMAIN), idl.Relevance)
    new = take_latched(participant, RelevanceV2)
    assert old.state_names == new.state_names and old.rule == new.rule
    assert list(old.affected) == list(new.affected) and list(old.mean_abs_shap) == list(new.mean_abs_shap)


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


def deep_request(exp2, n):
    """A Deep SHAP request of n observed rows; returns the rows and the request."""
    d, _ = exp2
    t = load_safetensors(d / "deep" / "shap_values.safetensors")
    rows = np.resize(t["observations"], (n, 31))
    state, action = rows[:, :23].ravel().tolist(), rows[:, 23:].ravel().tolist()
    return rows, idl.ExplainRequest(method="deep", state=state, action=action, rows=n)


def check_deep_reply(exp2, rows, reply):
    """The reply's attributions, checked for efficiency against NumPy on 50 rows."""
    d, _ = exp2
    n = len(rows)
    assert reply.success, reply.message
    phi = np.array(reply.attributions).reshape(n, 23, 31)
    f = numpy_predict(d / "models", "fm", rows[:50])
    sums = phi[:50].sum(axis=2)
    gap = (sums - sums[0]) - (f - f[0])
    assert np.all(np.abs(gap) <= 1e-5 * (np.abs(f).max(axis=0) + 1e-9))
    return phi


def deep_rows(exp2, client, n, timeout):
    """Deep SHAP of n rows from CycloneDDS, checked for efficiency against NumPy; returns
    the attributions and the request."""
    rows, request = deep_request(exp2, n)
    phi = check_deep_reply(exp2, rows, client.call(request, timeout=timeout))
    return phi, {"method": "deep", "state": request.state, "action": request.action, "rows": n, "background": 0}


def test_multi_fragment_explanations_reach_cyclonedds_and_our_own_client(exp2, client, run_cli, tmp_path):
    """100 rows of Deep SHAP: a 570 KB reply over many DDS fragments reaches CycloneDDS and
    `causal-arm service call` alike (rustdds patched: DATA_FRAG with inline QoS)."""
    phi, request = deep_rows(exp2, client, 100, 60)
    path = tmp_path / "request.json"
    path.write_text(json.dumps(request))
    env = {"RMW_IMPLEMENTATION": "rmw_cyclonedds_cpp", "ROS_DOMAIN_ID": str(DOMAIN)}
    r = run_cli("service", "call", "/explainer/explain", "--type", "causal_arm_msgs/srv/Explain",
                "--json", f"@{path}", "--timeout", "60", env=env, timeout=120)
    assert r.returncode == 0, r.stderr[-800:]
    ours = np.array(json.loads(r.stdout)["attributions"]).reshape(100, 23, 31)
    np.testing.assert_allclose(ours, phi, rtol=1e-9, atol=1e-12)


def test_the_advertised_deep_limit_is_a_fresh_nodes_first_reply(exp2, causal_arm_bin, private_netns):
    """5.7 MB in 87 DATA_FRAG datagrams of 64 KB to CycloneDDS with the default socket
    receive buffer (208 KiB). Sent at once, most were lost and never repaired (0 of 3
    replies); the rustdds writer now paces a fragmented sample at 128 KiB per millisecond
    and advertises it in HEARTBEATs only once it is all out
    (patches/rustdds-large-sample-pacing.diff; 18 of 18, also under CPU load)."""
    from cyclonedds.domain import DomainParticipant

    d, _ = exp2
    env = dict(os.environ, RMW_IMPLEMENTATION="rmw_cyclonedds_cpp", ROS_DOMAIN_ID=str(DOMAIN + 1))
    params = ["-p", f"model_dir:={d / 'models'}", "-p", f"bag:={d / 'bag'}", "-p", f"cache:={d / 'cache'}",
              "-p", f"samples:={NODE_SAMPLES}"]
    with node_process(causal_arm_bin.parent / "causal_arm_explainer", params, env):
        fresh = idl.ServiceClient(DomainParticipant(DOMAIN + 1), "/explainer/explain", idl.ExplainRequest,
                                  idl.ExplainReply)
        assert fresh.wait_for_server(timeout=120)
        deep_rows(exp2, fresh, 1000, 30)


def test_the_advertised_deep_limit_reaches_our_own_client(exp2, explainer_node, run_cli, tmp_path):
    """1000 rows, the advertised Deep SHAP limit: 5.7 MB to `causal-arm service call`."""

    rows, request = deep_request(exp2, 1000)
    path = tmp_path / "request.json"
    path.write_text(json.dumps({"method": "deep", "state": request.state, "action": request.action,
                                "rows": 1000, "background": 0}))
    env = {"RMW_IMPLEMENTATION": "rmw_cyclonedds_cpp", "ROS_DOMAIN_ID": str(DOMAIN)}
    r = run_cli("service", "call", "/explainer/explain", "--type", "causal_arm_msgs/srv/Explain",
                "--json", f"@{path}", "--timeout", "60", env=env, timeout=120)
    assert r.returncode == 0, r.stderr[-800:]
    check_deep_reply(exp2, rows, SimpleNamespace(**json.loads(r.stdout)))


@pytest.mark.parametrize("distro", DISTROS)
def test_the_advertised_deep_limit_is_a_fresh_nodes_first_reply_to_rclpy(exp2, causal_arm_bin, distro, private_netns):
    """Real rclpy on rmw_fastrtps_cpp: three concurrent requests, 1000 rows (the advertised
    limit, a 5.7 MB reply) first, each answered with its own attributions, checked against NumPy."""
    from rclpy_peer import RclpyPeer

    d, _ = exp2
    env = dict(os.environ, RMW_IMPLEMENTATION="rmw_fastrtps_cpp", ROS_DOMAIN_ID=str(DOMAIN + 2))
    params = ["-p", f"model_dir:={d / 'models'}", "-p", f"bag:={d / 'bag'}", "-p", f"cache:={d / 'cache'}",
              "-p", f"samples:={NODE_SAMPLES}"]
    made = [deep_request(exp2, n) for n in (1000, 3, 100)]
    requests = [{"method": r.method, "state": r.state, "action": r.action, "rows": r.rows, "background": 0}
                for _, r in made]
    with node_process(causal_arm_bin.parent / "causal_arm_explainer", params, env) as explainer:
        with RclpyPeer(distro, "rclpy_explain_client", env) as peer:
            replies = peer.call(service="/explainer/explain", type="causal_arm_msgs/srv/Explain",
                                requests=requests, timeout=180)
        assert explainer.poll() is None, explainer.log()[-3000:]
    for (rows, _), reply in zip(made, replies):
        check_deep_reply(exp2, rows, SimpleNamespace(**reply))


def test_the_advertised_deep_limit_reaches_a_client_after_a_smaller_reply(exp2, participant, explainer_node):
    warmed = idl.ServiceClient(participant, "/explainer/explain", idl.ExplainRequest, idl.ExplainReply)
    assert warmed.wait_for_server(timeout=60)
    deep_rows(exp2, warmed, 100, 60)
    deep_rows(exp2, warmed, 1000, 60)


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
    # Bad report parameters are refused before the bag is read.
    for param, message in [("kappa:=0.0", 'parameter "kappa" = 0 is outside its range'),
                           ("method:=lime", 'unknown SHAP method "lime"')]:
        r = subprocess.run([str(binary), "--ros-args", "-p", "model_dir:=x", "-p", "bag:=y", "-p", param],
                           env=env, capture_output=True, text=True, timeout=60)
        assert r.returncode != 0 and message in r.stderr, r.stderr
    r = run_cli("generate", "exp1", "--profile", "quick", "--steps", "300", "--out", tmp_path / "exp1")
    assert r.returncode == 0, r.stderr
    r = subprocess.run([str(binary), "--ros-args", "-p", f"model_dir:={d / 'models'}", "-p", f"bag:={tmp_path / 'exp1'}"],
                       env=env, capture_output=True, text=True, timeout=60)
    assert r.returncode != 0 and "expected exp2" in r.stderr, r.stderr
