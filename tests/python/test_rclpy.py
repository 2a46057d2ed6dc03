"""Real rclpy, on rmw_fastrtps_cpp, under the Jazzy and the Kilted wheels, against our nodes:
what a ROS 2 user's own node sees of a run, of the trainer's services and of its parameters.
The rclpy side runs in its own venv (tests/ros2/setup.sh), driven by rclpy_peer.RclpyPeer."""

import json
import os
import subprocess
import time
from pathlib import Path

import pytest

from rclpy_peer import DISTROS, RclpyPeer

DOMAIN = 47
OUR_NODES = {"/causal_arm_sim", "/causal_arm_babbler", "/causal_arm_recorder"}
# Every topic of a launch, with its type (crates/protocol/src/topics.rs).
LAUNCH_TOPICS = {
    "/joint_states": "sensor_msgs/msg/JointState",
    "/end_effector/pose": "geometry_msgs/msg/PoseStamped",
    "/object/pose": "geometry_msgs/msg/PoseStamped",
    "/object/color": "causal_arm_msgs/msg/ObjectColor",
    "/magnet/state": "causal_arm_msgs/msg/MagnetState",
    "/clock": "rosgraph_msgs/msg/Clock",
    "/tf": "tf2_msgs/msg/TFMessage",
    "/tf_static": "tf2_msgs/msg/TFMessage",
    "/scene/markers": "visualization_msgs/msg/MarkerArray",
    "/robot_description": "std_msgs/msg/String",
    "/babbler/action": "causal_arm_msgs/msg/Action",
    "/recorder/ack": "rosgraph_msgs/msg/Clock",
}


@pytest.fixture(params=DISTROS)
def distro(request, private_netns):
    return request.param


def ros_env(**extra):
    return {**os.environ, "ROS_DOMAIN_ID": str(DOMAIN), "RMW_IMPLEMENTATION": "rmw_fastrtps_cpp",
            "RUST_LOG": "warn", **extra}


def bag_joint_states(bag):
    """The /joint_states a bag holds, decoded by CycloneDDS Python's CDR (not ours)."""
    from mcap.reader import make_reader

    import ros_idl as idl

    (path,) = bag.glob("*.mcap")
    with open(path, "rb") as f:
        return [idl.JointState.deserialize(m.data)
                for _, c, m in make_reader(f).iter_messages() if c.topic == "/joint_states"]


def watch_graph(peer, until, every=0.05):
    """Polls the rclpy node's graph until `until()` is true; returns [(time, graph)]."""
    seen = []
    while not until():
        seen.append((peer.now(), peer.graph()))
        time.sleep(every)
    return seen


def test_an_rclpy_node_that_was_running_gets_every_step_of_a_launch_and_its_node_names(
        distro, causal_arm_bin, tmp_path):
    """The simulator publishes its first step only once discovery with the participants
    already present has settled both ways (patches/rustdds-early-heartbeats.diff,
    rustdds-discovery-settled.diff): before, an rclpy echo missed the first ~1.2 s of a run."""
    steps = 2000
    with RclpyPeer(distro, "rclpy_watcher", ros_env()) as peer:
        assert peer.info["rmw"] == "rmw_fastrtps_cpp"
        peer.subscribe(topic="/joint_states", type="sensor_msgs/msg/JointState", qos={"depth": 5000})
        own_hashes = {t: peer.own_type_hash(type=t) for t in set(LAUNCH_TOPICS.values())}
        launch = subprocess.Popen([str(causal_arm_bin), "launch", "exp1", "--steps", str(steps), "--seed", "3",
                                   "--out", str(tmp_path / "bag")], env=ros_env(),
                                  stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        endpoints = []
        graphs = watch_graph(peer, lambda: launch.poll() is not None
                             or endpoints.append(peer.endpoints_of(topics=list(LAUNCH_TOPICS))))
        out, err = launch.communicate(timeout=120)
        assert launch.returncode == 0, err[-3000:]
        samples = peer.take(topic="/joint_states", count=steps, timeout=5)
        # Each node's participant says goodbye as it exits (patches/rustdds-dispose-before-stop.diff):
        # otherwise `ros2 node list` keeps showing it until its lease (20 s) runs out.
        gone_by = time.monotonic() + 5
        while OUR_NODES & set(peer.graph()["nodes"]) and time.monotonic() < gone_by:
            time.sleep(0.1)
        lingering = OUR_NODES & set(peer.graph()["nodes"])

    stamps = [s["msg"]["header"]["stamp"] for s in samples]
    assert stamps[:1] == [{"sec": 0, "nanosec": 0}], f"the first step never reached rclpy ({distro}): {stamps[:1]}"
    times = [st["sec"] + st["nanosec"] * 1e-9 for st in stamps]
    assert len(samples) == steps, f"rclpy got {len(samples)} of {steps} steps"
    assert times == sorted(set(times)), "steps out of order or repeated"
    recorded = bag_joint_states(tmp_path / "bag")
    assert [(s["msg"]["name"], s["msg"]["position"], s["msg"]["velocity"]) for s in samples] == \
        [(list(m.name), list(m.position), list(m.velocity)) for m in recorded], "rclpy's samples are the bag's"

    for topic, type_ in LAUNCH_TOPICS.items():
        ours = [e for seen in endpoints for e in seen[topic]["publishers"] if "/" + e["node_name"] in OUR_NODES]
        assert ours, (f"rclpy never saw a publisher of {topic} among our nodes: "
                      f"{[seen[topic]['publishers'] for seen in endpoints][-1:]}")
        assert {(e["topic_type"], e["type_hash"]) for e in ours} == {(type_, own_hashes[type_])}, (topic, ours[0])
    # What a bag needs is sent reliably; the description is latched (`ros2 topic info -v`).
    qos = {t: {(e["reliability"], e["durability"]) for seen in endpoints for e in seen[t]["publishers"]}
           for t in ("/joint_states", "/robot_description")}
    assert qos == {"/joint_states": {("RELIABLE", "VOLATILE")}, "/robot_description": {("RELIABLE", "TRANSIENT_LOCAL")}}, qos
    named = set().union(*(set(g["nodes"]) for _, g in graphs))
    assert OUR_NODES <= named, f"node names rclpy saw: {sorted(named)}"
    # `ros2 node info`: each node's own publishers and subscriptions, with their types.
    def seen_of(node, kind):
        return {(topic, tuple(types)) for _, g in graphs
                for topic, types in g["nodes"].get(node, {}).get(kind, {}).items()}
    babbler, recorder = "/causal_arm_babbler", "/causal_arm_recorder"
    sim_topics = {t: ty for t, ty in LAUNCH_TOPICS.items() if t not in ("/babbler/action", "/recorder/ack")}
    assert {(t, (ty,)) for t, ty in sim_topics.items()} <= seen_of("/causal_arm_sim", "publishers")
    assert ("/babbler/action", ("causal_arm_msgs/msg/Action",)) in seen_of(babbler, "publishers")
    assert ("/joint_states", ("sensor_msgs/msg/JointState",)) in seen_of(babbler, "subscriptions")
    assert ("/recorder/ack", ("rosgraph_msgs/msg/Clock",)) in seen_of(recorder, "publishers")
    # The recorder records every topic but its own acks and the markers (drawn from the rest).
    recorded = {(t, (ty,)) for t, ty in LAUNCH_TOPICS.items() if t not in ("/recorder/ack", "/scene/markers")}
    assert recorded <= seen_of(recorder, "subscriptions"), seen_of(recorder, "subscriptions")
    assert not lingering, f"still in rclpy's graph 5 s after the launch ended: {sorted(lingering)}"


@pytest.fixture(scope="module")
def model_dir(run_cli, tmp_path_factory):
    from conftest import bag_and_forward_model

    d = tmp_path_factory.mktemp("rclpy_trainer")
    bag_and_forward_model(run_cli, d, ["exp1", "--profile", "quick", "--steps", "1200", "--seed", "5"],
                          ["--epochs", "3", "--folds", "2", "--fm-hidden", "32,32"])
    r = run_cli("train", "--bag", d / "bag", "--model", "im-mono", "--epochs", "3", "--folds", "2", "--im-hidden",
                "32,32", "--out", d / "models", "--cache", d / "cache", timeout=300)
    assert r.returncode == 0, r.stderr
    return d / "models"


@pytest.fixture(scope="module", params=DISTROS)
def trainer_and_peer(request, model_dir, causal_arm_bin, private_netns_module):
    """Our trainer node on the Fast DDS service mapping, and an rclpy node of DISTRO beside it."""
    from conftest import node_process

    with node_process(causal_arm_bin.parent / "causal_arm_trainer", ["-p", f"model_dir:={model_dir}"],
                      ros_env()) as trainer:
        with RclpyPeer(request.param, "rclpy_client", ros_env()) as peer:
            yield trainer, peer


def predict_requests(rows_per_request, seed):
    """PredictNextState requests of the given sizes, with their inputs for the NumPy reference."""
    import numpy as np

    rng = np.random.default_rng(seed)
    made = []
    for rows in rows_per_request:
        state = np.concatenate([rng.normal(0, 0.3, (rows, 7)), rng.uniform(0.2, 0.6, (rows, 3))], axis=1)
        action = rng.normal(0, 0.05, (rows, 7))
        made.append((state, action, {"state": state.ravel().tolist(), "action": action.ravel().tolist(),
                                     "rows": rows}))
    return made


def check_predictions(model_dir, made, replies):
    """Each reply holds its own request's next states, as NumPy computes them (first 50 rows)."""
    import numpy as np
    from model_numpy import numpy_predict

    assert len(replies) == len(made)
    for (state, action, request), reply in zip(made, replies):
        assert reply["success"] and reply["rows"] == request["rows"], reply["message"]
        got = np.array(reply["next_state"]).reshape(request["rows"], 10)
        expected = numpy_predict(model_dir, "fm", np.concatenate([state[:50], action[:50]], axis=1))
        np.testing.assert_allclose(got[:50], expected, rtol=1e-4, atol=1e-5)


def test_rclpy_calls_the_trainer_services_and_gets_the_numpy_answer(trainer_and_peer, model_dir):
    trainer, peer = trainer_and_peer
    predict = {"service": "/trainer/predict_next_state", "type": "causal_arm_msgs/srv/PredictNextState"}
    # Eight at once, of 1 to 8 rows: within the services' default depth of 10 (rclpy loses
    # replies beyond it), each matched to its own request.
    made = predict_requests(range(1, 9), 0)
    check_predictions(model_dir, made, peer.call(**predict, requests=[m[2] for m in made]))
    # The advertised row limit (serve.rs MAX_ROWS): a 13.6 MB request and an 8 MB reply.
    made = predict_requests([100_000], 1)
    check_predictions(model_dir, made, peer.call(**predict, requests=[made[0][2]], timeout=180))

    (bad,) = peer.call(**predict, requests=[{"state": [0.0] * 9, "action": [0.0] * 7, "rows": 1}])
    assert not bad["success"] and "state has 9 values, expected rows × 10 = 10" in bad["message"]
    (info,) = peer.call(service="/trainer/model_info", type="causal_arm_msgs/srv/GetModelInfo",
                        requests=[{"model": "fm"}])
    assert info["success"] and info["models"] == ["fm", "im-mono"], info
    assert trainer.poll() is None, "the trainer must keep serving"


def test_rclpy_gets_the_numpy_answer_of_predict_action_and_rollout(trainer_and_peer, model_dir):
    """The inverse model ([s(t), ef(t+1)] → a(t)) and the FM chained over a rollout."""
    import numpy as np
    from model_numpy import numpy_predict

    trainer, peer = trainer_and_peer
    rng = np.random.default_rng(2)
    state = np.concatenate([rng.normal(0, 0.3, (5, 7)), rng.uniform(0.2, 0.6, (5, 3))], axis=1)
    ef_next = rng.uniform(0.2, 0.6, (5, 3))
    (reply,) = peer.call(service="/trainer/predict_action", type="causal_arm_msgs/srv/PredictAction",
                         requests=[{"state": state.ravel().tolist(), "next_state": ef_next.ravel().tolist(), "rows": 5}])
    assert reply["success"] and reply["action_names"] == [f"a{i}" for i in range(7)], reply["message"]
    expected = numpy_predict(model_dir, "im-mono", np.concatenate([state, ef_next], axis=1))
    np.testing.assert_allclose(np.array(reply["action"]).reshape(5, 7), expected, rtol=1e-4, atol=1e-5)

    actions = rng.normal(0, 0.05, (4, 7))
    (reply,) = peer.call(service="/trainer/rollout", type="causal_arm_msgs/srv/Rollout",
                         requests=[{"initial_state": state[0].tolist(), "actions": actions.ravel().tolist(), "steps": 4}])
    assert reply["success"], reply["message"]
    states, s = np.array(reply["states"]).reshape(4, 10), state[0]
    for k in range(4):
        s = numpy_predict(model_dir, "fm", np.concatenate([s, actions[k]])[None, :])[0]
        np.testing.assert_allclose(states[k], s, rtol=1e-4, atol=1e-5)
    assert trainer.poll() is None


def test_rclpy_sees_the_type_hash_of_every_endpoint_of_the_trainer(trainer_and_peer):
    """REP-2011: every endpoint of ours announces `typehash=RIHS01_...;` in USER_DATA, and
    rmw_fastrtps reads the same hash rclpy gives the type (its own endpoints' hashes)."""
    _, peer = trainer_and_peer
    node = "causal_arm_trainer"
    own = {t: peer.own_type_hash(type=t) for t in ("rcl_interfaces/msg/Log", "rcl_interfaces/msg/ParameterEvent")}
    wanted = {"/rosout": ("rcl_interfaces/msg/Log", "TRANSIENT_LOCAL"),
              "/parameter_events": ("rcl_interfaces/msg/ParameterEvent", "VOLATILE")}
    deadline = time.monotonic() + 10
    while True:  # the graph of a fresh rclpy node fills within a moment
        seen = peer.endpoints_of(topics=list(wanted))
        ours = {t: [e for e in seen[t]["publishers"] if e["node_name"] == node] for t in wanted}
        if all(ours.values()) or time.monotonic() > deadline:
            break
        time.sleep(0.1)
    for topic, (type_, durability) in wanted.items():
        # rcl's QoS for both (`ros2 topic info -v` shows the same as for an rclcpp node's).
        assert [(e["topic_type"], e["type_hash"], e["reliability"], e["durability"]) for e in ours[topic]] == \
            [(type_, own[type_], "RELIABLE", durability)], (topic, seen[topic])
    # A service's request topic carries the request message's hash, its reply topic the
    # response message's, as rclpy's own client's do (not the service type's).
    for service, type_ in (("/trainer/model_info", "causal_arm_msgs/srv/GetModelInfo"),
                           (f"/{node}/get_parameters", "rcl_interfaces/srv/GetParameters")):
        halves = [peer.own_type_hash(type=f"{type_}_{half}") for half in ("Request", "Response")]
        hashes = peer.service_endpoints(service=service, type=type_)
        assert hashes["server"] == hashes["client"] == halves, (service, hashes, halves)
    # The graph's own topic: every participant's writer (ours and rclpy's) with one hash.
    discovery = peer.endpoints(topic="ros_discovery_info", no_mangle=True)["publishers"]
    assert len(discovery) >= 2 and len({e["type_hash"] for e in discovery}) == 1, discovery
    assert discovery[0]["type_hash"] == peer.own_type_hash(type="rmw_dds_common/msg/ParticipantEntitiesInfo")


def test_rclpy_parameters_are_listed_described_and_refused_as_rclcpp_does(trainer_and_peer):
    _, peer = trainer_and_peer
    node = "/causal_arm_trainer"
    (listed,) = peer.call(service=f"{node}/list_parameters", type="rcl_interfaces/srv/ListParameters",
                          requests=[{}])
    assert {"folds", "profile", "use_sim_time", "model_dir"} <= set(listed["result"]["names"]), listed
    (described,) = peer.call(service=f"{node}/describe_parameters", type="rcl_interfaces/srv/DescribeParameters",
                             requests=[{"names": ["folds", "use_sim_time"]}])
    folds, sim_time = described["descriptors"]
    assert folds["read_only"] and not sim_time["read_only"]
    assert [(r["from_value"], r["to_value"]) for r in folds["integer_range"]] == [(2, 1_000_000)]
    (got,) = peer.call(service=f"{node}/get_parameters", type="rcl_interfaces/srv/GetParameters",
                       requests=[{"names": ["folds"]}])
    assert got["values"][0]["type"] == 2
    (set_,) = peer.call(service=f"{node}/set_parameters", type="rcl_interfaces/srv/SetParameters",
                        requests=[{"parameters": [{"name": "folds", "value": {"type": 2, "integer_value": -5}}]}])
    assert [(r["successful"], r["reason"]) for r in set_["results"]] == [
        (False, "parameter 'folds' cannot be set because it is read-only")]


def test_a_parameter_added_to_the_graph_file_is_declared_and_described_by_the_node(distro, causal_arm_bin, tmp_path):
    """`ros2 param describe /causal_arm_recorder chunk_compression`, from rclpy: the one entry
    added to launch_scripts/graph.toml is declared by the node with the file's description
    and choices, and holds the value it was given (the CLI's and the launch files' side is
    in test_graph_file.py)."""
    import tomllib

    from conftest import node_process
    graph = tomllib.loads((Path(__file__).resolve().parents[2] / "launch_scripts" / "graph.toml").read_text())
    (decl,) = [p for n in graph["nodes"] if n["name"] == "causal_arm_recorder"
               for p in n["params"] if p["name"] == "chunk_compression"]
    node = "/causal_arm_recorder"
    with node_process(causal_arm_bin.parent / "causal_arm_recorder",
                      ["-p", f"output:={tmp_path / 'bag'}", "-p", "chunk_compression:=lz4"], ros_env()):
        with RclpyPeer(distro, "rclpy_param_client", ros_env()) as peer:
            (described,) = peer.call(service=f"{node}/describe_parameters",
                                     type="rcl_interfaces/srv/DescribeParameters",
                                     requests=[{"names": ["chunk_compression"]}])
            (descriptor,) = described["descriptors"]
            assert descriptor["description"] == decl["description"]
            assert descriptor["additional_constraints"] == "one of: zstd, lz4, none"
            assert descriptor["type"] == 4 and descriptor["read_only"]
            (got,) = peer.call(service=f"{node}/get_parameters", type="rcl_interfaces/srv/GetParameters",
                               requests=[{"names": ["chunk_compression"]}])
            assert [(v["type"], v["string_value"]) for v in got["values"]] == [(4, "lz4")]


def set_trainer_use_sim_time(peer, value):
    """`ros2 param set /causal_arm_trainer use_sim_time VALUE`; returns the results."""
    (reply,) = peer.call(service="/causal_arm_trainer/set_parameters", type="rcl_interfaces/srv/SetParameters",
                         requests=[{"parameters": [{"name": "use_sim_time", "value": {"type": 1, "bool_value": value}}]}])
    return [(r["successful"], r["reason"]) for r in reply["results"]]


def test_a_runtime_parameter_change_takes_effect_and_is_published_on_parameter_events(trainer_and_peer):
    """use_sim_time is the one parameter our nodes take at run time (the rest are read-only):
    set from rclpy, the change is announced on /parameter_events as rclcpp does and the
    trainer starts reading /clock, with the Clock type's hash; set back, it stops."""
    _, peer = trainer_and_peer
    node = "causal_arm_trainer"
    peer.subscribe(topic="/parameter_events", type="rcl_interfaces/msg/ParameterEvent", qos={"depth": 100})
    clock_hash = peer.own_type_hash(type="rosgraph_msgs/msg/Clock")

    def clock_readers(want, timeout=10):
        deadline = time.monotonic() + timeout
        while True:
            found = [e for e in peer.endpoints(topic="/clock")["subscriptions"] if e["node_name"] == node]
            if bool(found) == want or time.monotonic() > deadline:
                return found
            time.sleep(0.05)

    assert clock_readers(False) == [], "a node on wall time reads no /clock"
    try:
        assert set_trainer_use_sim_time(peer, True) == [(True, "")]
        readers = clock_readers(True)
        assert [(e["topic_type"], e["type_hash"]) for e in readers] == [("rosgraph_msgs/msg/Clock", clock_hash)]
    finally:
        assert set_trainer_use_sim_time(peer, False) == [(True, "")]
    assert clock_readers(False) == [], "back on wall time, the /clock reader is gone"
    events = [e["msg"] for e in peer.take(topic="/parameter_events", count=2, timeout=10)]
    ours = [e for e in events if e["node"] == "/" + node]
    assert [[(p["name"], p["value"]["type"], p["value"]["bool_value"]) for p in e["changed_parameters"]]
            for e in ours] == [[("use_sim_time", 1, True)], [("use_sim_time", 1, False)]], events
    assert all(e["new_parameters"] == [] and e["deleted_parameters"] == [] for e in ours)


def test_an_rclpy_node_on_sim_time_follows_the_clock_of_a_launch(distro, causal_arm_bin, tmp_path):
    """`use_sim_time:=true` in a user's node: its clock is the simulator's /clock, which ends
    at the last step's time."""
    steps = 500
    with RclpyPeer(distro, "rclpy_on_sim_time", ros_env()) as peer:
        assert peer.set_own_parameters(values={"use_sim_time": True}) == [True]
        peer.subscribe(topic="/clock", type="rosgraph_msgs/msg/Clock", qos={"depth": 5000})
        r = subprocess.run([str(causal_arm_bin), "launch", "exp1", "--steps", str(steps), "--seed", "4",
                            "--out", str(tmp_path / "bag")], env=ros_env(), capture_output=True, text=True,
                           timeout=120)
        assert r.returncode == 0, r.stderr[-3000:]
        clocks = [c["msg"]["clock"] for c in peer.take(topic="/clock", count=steps, timeout=5)]
        now = peer.clock_now()
    ns = [c["sec"] * 1_000_000_000 + c["nanosec"] for c in clocks]
    recorded = bag_joint_states(tmp_path / "bag")
    last = recorded[-1].header.stamp
    assert len(ns) >= steps and ns == sorted(ns), f"{len(ns)} /clock samples for {steps} steps"
    assert now == ns[-1] == last.sec * 1_000_000_000 + last.nanosec, (now, ns[-3:], last)


def test_causal_arm_service_call_reaches_an_rclpy_server(distro, run_cli):
    """rmw_fastrtps's server answers only once it has matched the reply reader the request
    names (patches/ros2-client-service-reply-reader.diff): two calls, two right replies."""
    reply = {"success": True, "message": "served by rclpy", "models": ["fm", "im-mono"],
             "state_names": ["theta0", "theta1"], "action_names": ["a0"], "metrics_json": '{"x": 1}',
             "next_state_names": ["theta0'", "theta1'"]}
    with RclpyPeer(distro, "rclpy_server", ros_env()) as peer:
        peer.serve(service="/served_by_rclpy/model_info", type="causal_arm_msgs/srv/GetModelInfo", reply=reply)
        for model in ["fm", "im-mono"]:
            r = run_cli("service", "call", "/served_by_rclpy/model_info", "--type", "causal_arm_msgs/srv/GetModelInfo",
                        "--json", json.dumps({"model": model}), "--timeout", "30", env=ros_env(), timeout=60)
            assert r.returncode == 0, r.stderr[-2000:]
            assert json.loads(r.stdout) == reply
        served = [s["msg"]["model"] for s in peer.served(service="/served_by_rclpy/model_info", count=2, timeout=5)]
    assert served == ["fm", "im-mono"]


def test_rclpy_publishes_to_causal_arm_topic_echo(distro, causal_arm_bin):
    """Joint states with awkward floats (subnormal, -0.0, 1e300) and a non-ASCII frame id,
    bit for bit, every one, in order."""
    from test_dds_interop import _assert_joint_state_equal, _sample_json

    sent = [{**_sample_json(), "header": {**_sample_json()["header"], "stamp": {"sec": 1234 + i, "nanosec": i}}}
            for i in range(20)]
    echo = subprocess.Popen([str(causal_arm_bin), "topic", "echo", "/joint_states", "--type",
                             "sensor_msgs/msg/JointState", "--count", str(len(sent)), "--timeout", "60"],
                            env=ros_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    with RclpyPeer(distro, "rclpy_talker", ros_env()) as peer:
        # Once rclpy counts echo as matched, as a user's talker would; 50 ms apart.
        peer.publish(topic="/joint_states", type="sensor_msgs/msg/JointState", messages=sent, period=0.05,
                     wait_subscribers=1, timeout=30)
        out, err = echo.communicate(timeout=90)
    assert echo.returncode == 0, err[-3000:]
    got = [json.loads(line) for line in out.splitlines()]
    assert len(got) == len(sent), f"echo printed {len(got)} of {len(sent)}: {got[:1]}"
    for g, want in zip(got, sent):
        _assert_joint_state_equal(g, want)


def test_a_late_rclpy_node_gets_the_latched_robot_description_and_rosout(distro, causal_arm_bin):
    from conftest import node_process

    with node_process(causal_arm_bin.parent / "causal_arm_sim", [], ros_env()) as sim:
        time.sleep(1.0)  # the simulator is up and has published before rclpy joins
        with RclpyPeer(distro, "rclpy_late", ros_env()) as peer:
            latched = {"transient_local": True, "depth": 1}
            peer.subscribe(topic="/robot_description", type="std_msgs/msg/String", qos=latched)
            peer.subscribe(topic="/rosout", type="rcl_interfaces/msg/Log",
                           qos={"transient_local": True, "depth": 1000})
            description = peer.take(topic="/robot_description", count=1, timeout=20)
            # Other nodes of the domain (this module's trainer) keep their logs durable too,
            # and theirs may arrive first: wait for the simulator's.
            logs, deadline = [], time.monotonic() + 20
            while (not any(log["msg"]["name"] == "causal_arm_sim" for log in logs)
                   and time.monotonic() < deadline):
                logs += peer.take(topic="/rosout", count=1, timeout=1)
        assert sim.poll() is None, sim.log()[-3000:]
    assert len(description) == 1 and "<robot" in description[0]["msg"]["data"], description[:1]
    assert any(log["msg"]["name"] == "causal_arm_sim" for log in logs), sorted({log["msg"]["name"] for log in logs})


def test_rclpy_lists_the_trainers_services_with_their_types(trainer_and_peer):
    """`ros2 node info /causal_arm_trainer` as rclpy reads the graph."""
    _, peer = trainer_and_peer
    deadline = time.monotonic() + 10
    while True:
        services = peer.graph()["nodes"].get("/causal_arm_trainer", {}).get("services", {})
        if "/trainer/predict_next_state" in services or time.monotonic() > deadline:
            break
        time.sleep(0.1)
    expected = {
        "/trainer/predict_next_state": ["causal_arm_msgs/srv/PredictNextState"],
        "/trainer/predict_action": ["causal_arm_msgs/srv/PredictAction"],
        "/trainer/rollout": ["causal_arm_msgs/srv/Rollout"],
        "/trainer/model_info": ["causal_arm_msgs/srv/GetModelInfo"],
        "/causal_arm_trainer/set_parameters": ["rcl_interfaces/srv/SetParameters"],
    }
    assert {name: services.get(name) for name in expected} == expected, services


def test_causal_arm_play_reaches_an_rclpy_subscriber(distro, run_cli, causal_arm_bin, tmp_path):
    steps = 300
    r = run_cli("generate", "exp1", "--steps", str(steps), "--seed", "8", "--out", tmp_path / "bag")
    assert r.returncode == 0, r.stderr
    with RclpyPeer(distro, "rclpy_listener", ros_env()) as peer:
        peer.subscribe(topic="/joint_states", type="sensor_msgs/msg/JointState", qos={"depth": 5000})
        r = run_cli("play", tmp_path / "bag", "--rate", "0", "--topics", "/joint_states", env=ros_env())
        assert r.returncode == 0, r.stderr
        samples = peer.take(topic="/joint_states", count=steps, timeout=10)
    stamps = [(s["msg"]["header"]["stamp"]["sec"], s["msg"]["header"]["stamp"]["nanosec"]) for s in samples]
    assert len(samples) == steps, f"rclpy got {len(samples)} of {steps} played messages"
    assert stamps == sorted(set(stamps)) and stamps[0] == (0, 0)


def test_an_unsecured_rclpy_node_gets_nothing_from_a_secured_talker(distro, run_cli, causal_arm_bin, tmp_path):
    """A secured rclpy peer cannot be tested: the wheels' Fast DDS is built without DDS
    Security ("This Fast DDS version doesn't have the security libraries")."""
    keystore = tmp_path / "keystore"
    domain = {"ROS_DOMAIN_ID": str(DOMAIN)}
    for args in (("create-keystore", keystore), ("create-enclave", keystore, "/talker")):
        r = run_cli("security", *args, env=domain)
        assert r.returncode == 0, r.stderr
    secured = ros_env(ROS_SECURITY_ENABLE="true", ROS_SECURITY_STRATEGY="Enforce",
                      ROS_SECURITY_KEYSTORE=str(keystore), ROS_SECURITY_ENCLAVE_OVERRIDE="/talker")
    with RclpyPeer(distro, "rclpy_outsider", ros_env()) as peer:
        peer.subscribe(topic="/chatter", type="std_msgs/msg/String", qos={"depth": 100})
        got = []
        for env in (secured, ros_env()):  # then the control: the same talker unsecured
            talker = subprocess.run([str(causal_arm_bin), "topic", "pub", "/chatter", "--type",
                                     "std_msgs/msg/String", "--json", '{"data": "secret"}', "--count", "30",
                                     "--rate", "10"], env=env, capture_output=True, text=True, timeout=60)
            assert talker.returncode == 0, talker.stderr[-3000:]
            got.append(peer.take(topic="/chatter", count=1, timeout=2))
    assert got[0] == [], f"an unauthenticated rclpy node read {len(got[0])} secured samples"
    assert got[1], "the control failed: rclpy got nothing from the unsecured talker either"
