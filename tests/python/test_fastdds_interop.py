"""Fast DDS, the default ROS 2 middleware, as a peer of the graph (tests/fastdds/fastdds_peer.cpp
on Debian's libfastrtps, speaking as rmw_fastrtps does): topics both ways, and services both
ways with rmw_fastrtps's request/reply correlation. Messages are encoded and decoded on this
side by CycloneDDS Python's CDR (ros_idl), so neither end checks itself.

Runs only inside tests/netns-run (loopback only)."""

import json
import os
import shutil
import subprocess
import time

import numpy as np
import pytest

import fastdds
import ros_idl as idl
from conftest import node_process
from model_numpy import numpy_predict
from test_dds_interop import JOINT_NAMES, _as_dict, _assert_joint_state_equal, _sample_json

DOMAIN = 61
JOINT_STATE = "sensor_msgs::msg::dds_::JointState_"


@pytest.fixture(scope="module")
def peer():
    return fastdds.build()


def _bag_joint_states(bag):
    from mcap.reader import make_reader

    (path,) = bag.glob("*.mcap")
    with open(path, "rb") as f:
        return [idl.JointState.deserialize(m.data)
                for _, c, m in make_reader(f).iter_messages() if c.topic == "/joint_states"]


def test_fastdds_receives_joint_states_from_a_running_graph(peer, run_cli, tmp_path, private_netns):
    """From the moment it matched, a Fast DDS reader gets every step's joint state, in order,
    equal to what the bag holds, through to the last step. The simulator waits only for the
    graph's own readers, so a volatile outside reader may match a few steps late (as with
    rmw_fastrtps); what it missed before matching is a prefix, never a gap."""
    def receive_during_a_launch():
        # To a file, not a pipe: a full pipe would stall the peer while the graph runs.
        with open(tmp_path / "sub.out", "w") as out, open(tmp_path / "sub.err", "w") as err:
            sub = subprocess.Popen([str(peer), "sub", "rt/joint_states", JOINT_STATE, "3000", "240", "20"],
                                   env=fastdds.env(DOMAIN), stdout=out, stderr=err)
        try:
            time.sleep(1.0)  # the Fast DDS participant is up before the graph starts
            shutil.rmtree(tmp_path / "bag", ignore_errors=True)
            r = run_cli("launch", "exp1", "--steps", "3000", "--seed", "2", "--out", tmp_path / "bag",
                        env={"ROS_DOMAIN_ID": str(DOMAIN)}, timeout=300)
            assert r.returncode == 0, r.stderr[-2000:]
            sub.wait(timeout=60)
        finally:
            if sub.poll() is None:
                sub.kill()
                sub.wait()
        fastdds.check_upstream_abort((tmp_path / "sub.err").read_text())
        assert sub.returncode == 0, (tmp_path / "sub.err").read_text()

    fastdds.retry_upstream_abort(receive_during_a_launch)
    got = [idl.JointState.deserialize(bytes.fromhex(line)) for line in (tmp_path / "sub.out").read_text().splitlines()]
    recorded = _bag_joint_states(tmp_path / "bag")
    assert len(recorded) == 3000
    assert len(got) >= 1000, f"Fast DDS matched only for the last {len(got)} of 3000 steps"
    assert got == recorded[-len(got):], "every sample since matching, once each, in order, as the bag holds it"
    assert len(got[0].name) == 7 and np.all(np.isfinite(got[0].position))


def test_our_echo_receives_a_fastdds_publisher(peer, causal_arm_bin, private_netns):
    want = _sample_json()
    samples = []
    for i in range(3):
        msg = idl.JointState(header=idl.Header(stamp=idl.Time(sec=1234 + i, nanosec=567890123),
                                               frame_id=want["header"]["frame_id"]),
                             name=JOINT_NAMES, position=want["position"], velocity=want["velocity"],
                             effort=want["effort"])
        samples.append(msg)

    def echo_a_fastdds_publisher():
        echo = subprocess.Popen([str(causal_arm_bin), "topic", "echo", "/joint_states", "--type",
                                 "sensor_msgs/msg/JointState", "--count", "3", "--timeout", "60"],
                                env=fastdds.env(DOMAIN + 1), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        pub = subprocess.run([str(peer), "pub", "rt/joint_states", JOINT_STATE, "60"],
                             input="".join(m.serialize().hex() + "\n" for m in samples),
                             env=fastdds.env(DOMAIN + 1), capture_output=True, text=True, timeout=90)
        if pub.returncode != 0:
            echo.kill()
        out, err = echo.communicate(timeout=60)
        fastdds.check_upstream_abort(pub.stderr)
        assert pub.returncode == 0, pub.stderr
        assert echo.returncode == 0, err
        return out

    out = fastdds.retry_upstream_abort(echo_a_fastdds_publisher)
    lines = [json.loads(line) for line in out.splitlines() if line.strip()]
    assert len(lines) == 3
    for got, sent in zip(lines, samples):
        _assert_joint_state_equal(got, _as_dict(sent))


def _serve_two_calls(peer, run_cli, reply):
    """A Fast DDS server of /trainer/model_info answers two `causal-arm service call`s;
    returns what the server printed (one line per request)."""
    server = subprocess.Popen([str(peer), "serve", "/trainer/model_info", idl.GetModelInfoRequest.__idl_typename__,
                               idl.GetModelInfoReply.__idl_typename__, "2", "90", fastdds.enhanced_payload(reply).hex()],
                              env=fastdds.env(DOMAIN + 2), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        for model in ["fm", "im-mono"]:
            r = run_cli("service", "call", "/trainer/model_info", "--type", "causal_arm_msgs/srv/GetModelInfo",
                        "--json", json.dumps({"model": model}), "--timeout", "30",
                        env={"ROS_DOMAIN_ID": str(DOMAIN + 2), "RMW_IMPLEMENTATION": "rmw_fastrtps_cpp"}, timeout=60)
            if r.returncode != 0:  # say what the Fast DDS side saw too
                server.kill()
                out, err = server.communicate()
                fastdds.check_upstream_abort(err)
                pytest.fail(f"service call failed:\n{r.stderr[-2000:]}\nFast DDS server:\n{out[-1000:]}\n{err[-1000:]}")
            got = json.loads(r.stdout)
            assert got["success"] and got["message"] == reply.message and got["models"] == reply.models
            assert got["state_names"] == reply.state_names and got["metrics_json"] == reply.metrics_json
        out, err = server.communicate(timeout=60)
    finally:
        if server.poll() is None:
            server.kill()
            server.wait()
    fastdds.check_upstream_abort(err)
    assert server.returncode == 0, err
    return out


def test_our_service_call_reaches_a_fastdds_server_naming_its_reply_reader(peer, run_cli, private_netns):
    """`causal-arm service call` (rmw_fastrtps mapping) sends its reply reader's GUID as the
    related sample identity, so the Fast DDS server waits for that reader before replying
    (patches/ros2-client-service-reply-reader.diff); two calls, two right replies."""
    reply = idl.GetModelInfoReply(success=True, message="served by Fast DDS", models=["fm", "im-mono"],
                                  state_names=["theta0", "theta1"], action_names=["a0"], metrics_json='{"x": 1}')
    out = fastdds.retry_upstream_abort(lambda: _serve_two_calls(peer, run_cli, reply))
    requests = [line.split(" ") for line in out.splitlines()]
    assert [kind for kind, _ in requests] == ["reader", "reader"], "each request named its reply reader"
    assert [fastdds.from_enhanced(idl.GetModelInfoRequest, bytes.fromhex(h)).model for _, h in requests] == \
        ["fm", "im-mono"]


@pytest.fixture(scope="module")
def model_dir(run_cli, tmp_path_factory):
    d = tmp_path_factory.mktemp("fastdds_trainer")
    r = run_cli("generate", "exp1", "--profile", "quick", "--steps", "1200", "--seed", "5", "--out", d / "bag")
    assert r.returncode == 0, r.stderr
    r = run_cli("train", "--bag", d / "bag", "--model", "fm", "--epochs", "3", "--folds", "2", "--fm-hidden",
                "32,32", "--out", d / "models", "--cache", d / "cache", timeout=300)
    assert r.returncode == 0, r.stderr
    return d / "models"


@pytest.fixture(scope="module")
def trainer_node(model_dir, causal_arm_bin, private_netns_module):
    env = dict(os.environ, RMW_IMPLEMENTATION="rmw_fastrtps_cpp", ROS_DOMAIN_ID=str(DOMAIN + 3))
    with node_process(causal_arm_bin.parent / "causal_arm_trainer", ["-p", f"model_dir:={model_dir}"], env) as proc:
        yield proc


def _predict_requests(rows_per_request, seed):
    rng = np.random.default_rng(seed)
    out = []
    for rows in rows_per_request:
        state, action = rng.uniform(-1, 1, (rows, 10)), rng.uniform(-0.05, 0.05, (rows, 7))
        out.append((state, action, idl.PredictNextStateRequest(state=state.ravel().tolist(),
                                                               action=action.ravel().tolist(), rows=rows)))
    return out


def _check_predictions(model_dir, made, replies):
    for (state, action, request), reply in zip(made, replies):
        assert reply.success, reply.message
        got = np.array(reply.next_state).reshape(request.rows, 10)
        expected = numpy_predict(model_dir, "fm", np.hstack([state[:50], action[:50]]))
        np.testing.assert_allclose(got[:50], expected, rtol=1e-4, atol=1e-5)


def test_a_fastdds_client_gets_its_own_reply_to_each_of_several_concurrent_requests(peer, trainer_node, model_dir):
    """Eight requests written back to back, of 1 to 8 rows: every reply is matched to its
    request by related sample identity and holds that request's predictions."""
    made = _predict_requests(range(1, 9), 8)
    replies = fastdds.call(peer, DOMAIN + 3, "/trainer/predict_next_state", idl.PredictNextStateRequest,
                           idl.PredictNextStateReply, [m[2] for m in made], server=trainer_node)
    _check_predictions(model_dir, made, replies)
    assert [len(r.next_state) for r in replies] == [10 * n for n in range(1, 9)]
    info = fastdds.call(peer, DOMAIN + 3, "/trainer/model_info", idl.GetModelInfoRequest, idl.GetModelInfoReply,
                        [idl.GetModelInfoRequest(model="fm")], server=trainer_node)[0]
    assert info.success and "fm" in info.models, info.message


def test_the_advertised_row_limit_reaches_a_fastdds_client(peer, trainer_node, model_dir):
    """100,000 rows: a 13.6 MB request from Fast DDS and an 8 MB reply back."""
    made = _predict_requests([100_000], 9)
    replies = fastdds.call(peer, DOMAIN + 3, "/trainer/predict_next_state", idl.PredictNextStateRequest,
                           idl.PredictNextStateReply, [m[2] for m in made], timeout=120, server=trainer_node)
    _check_predictions(model_dir, made, replies)


def test_every_endpoint_announces_its_type_hash_in_user_data(peer, causal_arm_bin, private_netns):
    """REP-2011: our publishers, subscriptions and service endpoints announce
    `typehash=RIHS01_...;` in USER_DATA, as Fast DDS sees them in discovery (rustdds and
    ros2-client patched to send endpoint USER_DATA). CycloneDDS Python 11.0.1 crashes on
    taking any builtin DCPSPublication sample, so Fast DDS is the witness here."""
    domain = DOMAIN + 5
    env = fastdds.env(domain)
    wanted = [("writer", "rt/joint_states"), ("reader", "rt/joint_states"),
              ("writer", "rq/trainer/model_infoRequest"), ("reader", "rr/trainer/model_infoReply")]
    # ros2-client's own endpoints too (patched): discovery info, rosout, parameter events,
    # the clock reader of a node on sim time (typed rosgraph_msgs/Clock as ROS 2 publishes it) and every
    # parameter service; the values are those Jazzy publishes.
    published = {
        ("writer", "ros_discovery_info"): "91a0593bacdcc50ea9bdcf849a938b128412cc1ea821245c663bcd26f83c295e",
        ("writer", "rt/rosout"): "e28ce254ca8abc06abf92773b74602cdbf116ed34fbaf294fb9f81da9f318eac",
        ("writer", "rt/parameter_events"): "043e627780fcad87a22d225bc2a037361dba713fca6a6b9f4b869a5aa0393204",
        ("reader", "rt/clock"): "692f7a66e93a3c83e71765d033b60349ba68023a8c689a79e48078bcb5c58564",
        ("reader", "rq/causal_arm_topic_echo/get_parametersRequest"):
            "bf9803d5c74cf989a5de3e0c2e99444599a627c7ff75f97b8c05b01003675cbc",
    }
    # Our processes outlive the discovery window (they are killed after it).
    with open(os.devnull, "w") as null:
        ours = [
            subprocess.Popen([str(causal_arm_bin), "topic", "pub", "/joint_states", "--type",
                              "sensor_msgs/msg/JointState", "--json", json.dumps(_sample_json()), "--count", "2000",
                              "--rate", "20"], env=env, stdout=null, stderr=null),
            # On sim time, so it reads /clock (nodes on wall time have no /clock reader).
            subprocess.Popen([str(causal_arm_bin), "topic", "echo", "/joint_states", "--type",
                              "sensor_msgs/msg/JointState", "--count", "100000", "--timeout", "120",
                              "--ros-args", "-p", "use_sim_time:=true"], env=env,
                             stdout=null, stderr=null),
            subprocess.Popen([str(causal_arm_bin), "service", "call", "/trainer/model_info", "--type",
                              "causal_arm_msgs/srv/GetModelInfo", "--timeout", "120"], env=env, stdout=null,
                             stderr=null),
        ]
    try:
        endpoints = fastdds.discover(peer, domain, [*wanted, *published], timeout=60)
    finally:
        for p in ours:
            p.kill()
            p.wait()
    for key in wanted:
        type_name, user_data = endpoints[key]
        assert user_data.startswith(b"typehash=RIHS01_") and user_data.endswith(b";"), (key, user_data)
    for kind in ["writer", "reader"]:
        assert endpoints[(kind, "rt/joint_states")][1] == \
            b"typehash=RIHS01_a13ee3a330e346c9d87b5aa18d24e11690752bd33a0350f11c5882bc9179260e;"
    assert endpoints[("writer", "rq/trainer/model_infoRequest")][1] == \
        endpoints[("reader", "rr/trainer/model_infoReply")][1], "both halves announce the service's hash"
    missing = sorted(key for key, (_, user_data) in endpoints.items() if not user_data.startswith(b"typehash=RIHS01_"))
    assert not missing, f"endpoints without a type hash: {missing}"
    for key, hex_hash in published.items():
        assert endpoints[key][1] == f"typehash=RIHS01_{hex_hash};".encode(), (key, endpoints[key])
    assert endpoints[("reader", "rt/clock")][0] == "rosgraph_msgs::msg::dds_::Clock_"
