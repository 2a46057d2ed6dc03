"""Datasets as real ROS 2 bags: `causal-arm generate` (in-process) and `causal-arm launch`
(three DDS node processes) for both experiments, read back with independent readers
(rosbags AnyReader, mcap-ros2-support), checked for completeness and physics.
"""

import json
import os
import pathlib
import signal
import subprocess
import time

import numpy as np
import pytest
from mcap_ros2.reader import read_ros2_messages
from rosbags.highlevel import AnyReader

from conftest import custom_data

STATE_TOPICS = ["/joint_states", "/end_effector/pose", "/object/pose", "/object/color", "/magnet/state",
                "/clock", "/tf", "/scene/markers"]
STEP_TOPICS = STATE_TOPICS + ["/babbler/action"]
LATCHED_TOPICS = ["/robot_description", "/tf_static"]
STEP_NS = 10 / 240 * 1e9


def read_bag(path):
    """topic -> list of (log_time, msg) with rosbags, which takes the types from the bag."""
    out = {}
    with AnyReader([pathlib.Path(path)]) as reader:
        for conn, t, raw in reader.messages():
            out.setdefault(conn.topic, []).append((t, reader.deserialize(raw, conn.msgtype)))
    return out


def stamp_ns(msg):
    return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec


@pytest.fixture(scope="module")
def exp1_bag(run_cli, tmp_path_factory):
    out = tmp_path_factory.mktemp("bags") / "exp1"
    r = run_cli("generate", "exp1", "--steps", "600", "--seed", "3", "--out", out, timeout=300)
    assert r.returncode == 0, r.stderr
    assert str(out) in r.stdout
    return out


@pytest.fixture(scope="module")
def exp2_bag(run_cli, tmp_path_factory):
    out = tmp_path_factory.mktemp("bags") / "exp2"
    r = run_cli("generate", "exp2", "--episodes", "4", "--seed", "5", "--out", out, timeout=300)
    assert r.returncode == 0, r.stderr
    return out


@pytest.mark.parametrize("which,steps", [("exp1", 600), ("exp2", 2000)])
def test_bag_is_complete_and_readable(which, steps, exp1_bag, exp2_bag):
    bag = exp1_bag if which == "exp1" else exp2_bag
    topics = read_bag(bag)
    for topic in STEP_TOPICS:
        assert len(topics[topic]) == steps, f"{topic}: {len(topics[topic])} != {steps}"
    for topic in LATCHED_TOPICS:
        assert len(topics[topic]) == 1, topic
    stamps = [stamp_ns(m) for _, m in topics["/joint_states"]]
    assert all(b > a for a, b in zip(stamps, stamps[1:])), "stamps must strictly increase"
    gaps = np.diff(stamps)
    assert np.all(np.abs(gaps - STEP_NS) <= 1), f"gaps: {set(gaps.tolist())}"
    # Every step's topics share its stamp, and the action answers that state.
    for topic in ("/end_effector/pose", "/object/pose", "/magnet/state", "/babbler/action"):
        assert [stamp_ns(m) for _, m in topics[topic]] == stamps, topic
    # mcap-ros2-support decodes everything with the schemas embedded in the bag.
    mcap_file = next(pathlib.Path(bag).glob("*.mcap"))
    count = sum(1 for _ in read_ros2_messages(str(mcap_file)))
    assert count == steps * len(STEP_TOPICS) + len(LATCHED_TOPICS)


def test_exp1_actions_follow_the_babbling_distribution(exp1_bag):
    topics = read_bag(exp1_bag)
    targets = np.array([m.joint_targets for _, m in topics["/babbler/action"]])
    positions = np.array([m.position for _, m in topics["/joint_states"]])
    assert targets.shape == (600, 7)
    assert np.all(np.abs(targets.mean(axis=0)) < 0.1)
    assert np.all(np.abs(targets.std(axis=0) - 0.35) < 0.05)
    deltas = np.array([m.joint_deltas for _, m in topics["/babbler/action"]])
    np.testing.assert_allclose(deltas, targets - positions, atol=1e-12)


SCRIPTED, NORMAL, CATEGORICAL = 0, 1, 2


def test_each_action_says_how_it_was_drawn(exp1_bag, exp2_bag):
    """Action.design, read with rosbags from the schema in the bag: exp1 draws every joint
    from the paper's N(0, 0.35^2) whatever the state; exp2 scripts its reaching and placing,
    draws its moves around the joints it is at and its magnet while babbling, and the kept
    moves are N(0, 1) in units of their spread."""
    topics = read_bag(exp1_bag)
    for _, m in topics["/babbler/action"]:
        assert [d.family for d in m.design] == [NORMAL] * 7
        assert all(d.center == 0.0 and d.scale == 0.35 and d.lower <= t <= d.upper
                   for d, t in zip(m.design, m.joint_targets))
    assert "N(0, 0.35^2)" in custom_data(exp1_bag)["causal_arm.design"]

    topics = read_bag(exp2_bag)
    positions = [m.position for _, m in topics["/joint_states"]]
    families, z = [], []
    for (_, m), q in zip(topics["/babbler/action"], positions):
        assert len(m.design) == 8
        joints, magnet = m.design[:7], m.design[7]
        assert len({d.family for d in joints}) == 1, "the joints are drawn together"
        families.append((joints[0].family, magnet.family))
        if magnet.family == CATEGORICAL:
            assert m.magnet in magnet.values and abs(sum(magnet.probabilities) - 1) < 1e-12
        if joints[0].family == NORMAL:
            for d, t, qi in zip(joints, m.joint_targets, q):
                assert d.center == qi and d.lower <= t <= d.upper and d.tries == 20
                if d.lower < t < d.upper:
                    z.append((t - d.center) / d.scale)
    kinds = {f for f in families}
    assert (SCRIPTED, SCRIPTED) in kinds, "the reaching is scripted"
    assert (NORMAL, CATEGORICAL) in kinds, "babbling draws its moves and the magnet"
    assert (NORMAL, SCRIPTED) in kinds, "moves while holding or releasing"
    assert abs(np.mean(z)) < 0.05 and 0.85 < np.std(z) < 1.05, (np.mean(z), np.std(z))
    assert "scripted" in custom_data(exp2_bag)["causal_arm.design"]


def test_exp2_cube_moves_only_while_held(exp2_bag):
    topics = read_bag(exp2_bag)
    z = np.array([m.pose.position.z for _, m in topics["/object/pose"]])
    holding = np.array([m.holding for _, m in topics["/magnet/state"]])
    on = np.array([m.on for _, m in topics["/magnet/state"]])
    colour = np.array([[m.color.r, m.color.g, m.color.b] for _, m in topics["/object/color"]])
    table = 0.2 + 0.025
    assert holding.sum() > 0, "the cube was never picked"
    assert np.all(on[holding]), "holding implies the magnet is on"
    lifted = z > table + 0.02
    # The cube is above the table only while held or within 40 steps after a release.
    released_recently = np.zeros_like(holding)
    last_hold = -1000
    for i, h in enumerate(holding):
        if h:
            last_hold = i
        released_recently[i] = i - last_hold <= 40
    assert np.all(~lifted | holding | released_recently), np.where(lifted & ~holding & ~released_recently)
    assert lifted[holding].any(), "held cube never lifted"
    # After release it falls back to the table.
    settled = ~holding & ~released_recently
    assert np.all(np.abs(z[settled] - table) < 0.01) or np.all(z[settled] < table + 0.01)
    # Colour constant within an episode, different across episodes.
    episodes = colour.reshape(4, 500, 3)
    assert np.all(episodes == episodes[:, :1, :])
    assert len({tuple(e[0]) for e in episodes}) == 4


def test_bag_stats_describe_the_physics_against_the_bag_itself(run_cli, exp2_bag, tmp_path, repo_root):
    """`bag stats` (issue 18) checked against what rosbags reads: the cube-on-floor share,
    the realized joint spread and the joints' speeds against the URDF velocity limits,
    recomputed here from the messages."""
    r = run_cli("bag", "stats", exp2_bag)
    assert r.returncode == 0, r.stderr
    stats = json.loads(r.stdout)
    topics = read_bag(exp2_bag)
    z = np.array([m.pose.position.z for _, m in topics["/object/pose"]])
    theta = np.array([m.position for _, m in topics["/joint_states"]]).reshape(4, 500, 7)
    assert stats["transitions"] == 4 * 499
    # Rows are s(t) of each transition: every step of an episode but its last.
    on_floor = (z.reshape(4, 500)[:, :-1] < 0.2 - 0.025).mean()
    assert stats["cube_on_floor_share"] == pytest.approx(on_floor)
    realized = np.diff(theta, axis=1).reshape(-1, 7).std(axis=0)
    assert stats["realized_spread"] == pytest.approx(realized.tolist(), rel=1e-4)
    import xml.etree.ElementTree as ET
    urdf = ET.parse(repo_root / "urdf" / "iiwa14_magnet.urdf").getroot()
    limits = np.array([float(j.find("limit").get("velocity")) for j in urdf.iter("joint")
                       if j.get("type") == "revolute"])
    speed = np.abs(np.diff(theta, axis=1)).reshape(-1, 7) / (10 / 240) / limits
    assert stats["overspeed_max"] == pytest.approx(speed.max(), rel=1e-3)
    assert stats["overspeed_share"] == pytest.approx((speed.max(axis=1) > 1.01).mean())
    assert stats["overspeed_max"] <= 1.001, "the kinematic servo keeps the limits"
    assert 0 <= stats["in_table_share"] <= 1 and stats["penetration_max"] >= 0
    assert 0 < stats["grasp_success"] <= 1 and stats["switch_ons"] > 0
    r = run_cli("bag", "stats", tmp_path / "missing")
    assert r.returncode == 1 and "missing" in r.stderr, r.stderr


def test_metadata_yaml_describes_the_bag(exp1_bag):
    import yaml

    meta = yaml.safe_load((pathlib.Path(exp1_bag) / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert meta["storage_identifier"] == "mcap"
    counts = {t["topic_metadata"]["name"]: t["message_count"] for t in meta["topics_with_message_count"]}
    assert counts["/joint_states"] == 600 and counts["/robot_description"] == counts["/tf_static"] == 1
    assert meta["message_count"] == 600 * len(STEP_TOPICS) + len(LATCHED_TOPICS)


def test_every_topic_carries_its_rihs01_type_hash_as_rosbags_computes_it(exp1_bag):
    """REP-2011 hashes in metadata.yaml (type_description_hash) and in each MCAP channel's
    metadata (topic_type_hash), as rosbag2 on Jazzy writes them, equal rosbags' own
    computation from the type definitions (standard Jazzy types and the bag's own)."""
    import yaml
    from mcap.reader import make_reader
    from rosbags.typesys import Stores, get_typestore

    bag = pathlib.Path(exp1_bag)
    meta = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    in_yaml = {t["topic_metadata"]["name"]: t["topic_metadata"]["type_description_hash"]
               for t in meta["topics_with_message_count"]}
    (mcap_path,) = bag.glob("*.mcap")
    with open(mcap_path, "rb") as f:
        channels = make_reader(f).get_summary().channels.values()
        in_mcap = {c.topic: c.metadata["topic_type_hash"] for c in channels}
    assert in_yaml == in_mcap
    with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        for conn in reader.connections:
            assert in_yaml[conn.topic] == reader.typestore.hash_rihs01(conn.msgtype), conn.topic
    assert in_yaml["/joint_states"] == "RIHS01_a13ee3a330e346c9d87b5aa18d24e11690752bd33a0350f11c5882bc9179260e"


@pytest.mark.parametrize("args,needle", [
    (["generate", "exp3", "--out", "X"], 'unknown experiment "exp3"'),
    (["generate", "exp1", "--steps", "0", "--out", "X"], "--steps must be a positive number, got 0"),
    (["generate", "exp1", "--steps", "-5", "--out", "X"], "--steps must be a positive number, got -5"),
    (["generate", "exp2", "--episodes", "0", "--out", "X"], "--episodes must be a positive number"),
    (["generate", "exp1", "--profile", "huge", "--out", "X"], 'unknown profile "huge"'),
    (["generate", "exp2", "--arm", "floppy", "--out", "X"], 'unknown arm mode "floppy"'),
])
def test_bad_generate_arguments(run_cli, tmp_path, args, needle):
    args = [str(tmp_path / "out") if a == "X" else a for a in args]
    r = run_cli(*args)
    assert r.returncode != 0
    assert needle in r.stderr, r.stderr
    assert not (tmp_path / "out").exists(), "nothing may be written for bad input"


def test_existing_bag_is_refused_unless_overwrite(run_cli, exp1_bag, tmp_path):
    before = sorted(p.name for p in pathlib.Path(exp1_bag).iterdir())
    r = run_cli("generate", "exp1", "--steps", "10", "--out", exp1_bag)
    assert r.returncode != 0 and "overwrite" in r.stderr, r.stderr
    assert sorted(p.name for p in pathlib.Path(exp1_bag).iterdir()) == before
    copy = tmp_path / "again"
    assert run_cli("generate", "exp1", "--steps", "10", "--out", copy).returncode == 0
    r = run_cli("generate", "exp1", "--steps", "20", "--out", copy, "--overwrite")
    assert r.returncode == 0, r.stderr
    assert len(read_bag(copy)["/joint_states"]) == 20


def test_unwritable_directory(run_cli, tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("not a directory")
    r = run_cli("generate", "exp1", "--steps", "10", "--out", blocker / "bag")
    assert r.returncode != 0
    assert str(blocker) in r.stderr


def _canonical(bag):
    """Bag content as comparable data: topic -> [(log_time, normalized message)]."""
    topics = read_bag(bag)

    def norm(v):
        if hasattr(v, "__dataclass_fields__"):
            return {k: norm(getattr(v, k)) for k in v.__dataclass_fields__ if k != "__msgtype__"}
        if isinstance(v, np.ndarray):
            return v.tolist()
        if isinstance(v, list):
            return [norm(x) for x in v]
        return v

    return {t: [(ts, norm(m)) for ts, m in msgs] for t, msgs in topics.items()}


def assert_same_bag(bag, reference, differs: str):
    """`bag` holds the topics of `reference`, message for message and stamp for stamp;
    a topic that does not fails as "<topic> <differs>"."""
    a, b = _canonical(bag), _canonical(reference)
    assert a.keys() == b.keys()
    for topic in a:
        assert a[topic] == b[topic], f"{topic} {differs}"


@pytest.mark.parametrize("flags, launch_flags", [([], []), (["--move-while-switching", "false"], []),
                                                 (["--arm", "dynamic"], []), ([], ["--composed"])])
def test_launch_over_dds_equals_generate(run_cli, causal_arm_bin, tmp_path, private_netns, flags,
                                         launch_flags):
    env = {"ROS_DOMAIN_ID": "17", "RUST_LOG": "warn"}
    dds = tmp_path / "dds"
    r = run_cli("launch", "exp2", "--episodes", "1", "--seed", "8", *flags, *launch_flags, "--out", dds,
                env=env, timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    assert str(dds) in r.stdout
    # Every node stops with the run: none is waited for until the launcher kills it.
    assert "did not stop" not in r.stderr, r.stderr[-3000:]
    local = tmp_path / "local"
    r = run_cli("generate", "exp2", "--episodes", "1", "--seed", "8", *flags, "--out", local)
    assert r.returncode == 0, r.stderr
    arm = "dynamic" if "dynamic" in flags else "kinematic"
    for bag in [dds, local]:
        assert custom_data(bag)["causal_arm.arm"] == arm, "the bag records how the arm moved"
    assert_same_bag(dds, local, "differs between launch and generate")


@pytest.mark.parametrize("composed", [False, True], ids=["processes", "composed"])
def test_sigint_mid_run_leaves_a_finalized_bag(causal_arm_bin, tmp_path, private_netns, composed):
    """Also: a CycloneDDS subscriber beside the running graph receives plausible states,
    also from nodes composed in one process (they still publish every topic on DDS)."""
    from cyclonedds.domain import DomainParticipant
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic
    from ros_idl import JointState, PoseStamped, ros_default_qos

    participant = DomainParticipant(18)
    js_reader = DataReader(participant, Topic(participant, "rt/joint_states", JointState), qos=ros_default_qos(100))
    ef_reader = DataReader(participant, Topic(participant, "rt/end_effector/pose", PoseStamped),
                           qos=ros_default_qos(100))
    env = {**os.environ, "ROS_DOMAIN_ID": "18", "RUST_LOG": "warn"}
    out = tmp_path / "interrupted"
    proc = subprocess.Popen([str(causal_arm_bin), "launch", "exp1", "--steps", "100000", "--seed", "1",
                             "--out", str(out)] + ["--composed"] * composed, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and not any(out.glob("*.mcap")):
        time.sleep(0.2)
    joint_states, ef_poses = [], []
    until = time.monotonic() + 4
    while time.monotonic() < until:
        joint_states += [m for m in js_reader.take(N=100) if isinstance(m, JointState)]
        ef_poses += [m for m in ef_reader.take(N=100) if isinstance(m, PoseStamped)]
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=120)
    topics = read_bag(out)
    n = len(topics["/joint_states"])
    assert 0 < n < 100000
    # The launcher reports what the bag holds, not the plan, and fails the interrupted run.
    how = "by nodes composed in one process" if composed else "over DDS"
    assert f"({n} of 100000 steps {how} in" in stdout, stdout
    assert proc.returncode == 1 and f"stopped after {n} of 100000 steps" in stderr, stderr[-2000:]
    for topic in STEP_TOPICS:
        assert len(topics[topic]) == n, topic
    assert (out / "metadata.yaml").exists()
    assert len(joint_states) >= 10 and len(ef_poses) >= 10
    limits = np.array([2.967, 2.094, 2.967, 2.094, 2.967, 2.094, 3.054])
    for m in joint_states:
        assert list(m.name) == [f"iiwa_joint_{i}" for i in range(1, 8)]
        assert np.all(np.abs(np.array(m.position)) <= limits + 1e-9)
    for m in ef_poses:
        p = m.pose.position
        assert m.header.frame_id == "world"
        assert 0.0 < np.hypot(p.x, p.y) < 1.4 and -0.5 < p.z < 1.4


def test_a_composed_node_that_fails_stops_the_others_naming_it(run_cli, tmp_path, private_netns):
    """Composed nodes share their process: the recorder failing (here it cannot create its
    bag) stops the simulator and the babbler at once, and the launch fails naming it."""
    blocker = tmp_path / "file"
    blocker.write_text("not a directory")
    env = {"ROS_DOMAIN_ID": "27", "RUST_LOG": "warn"}
    start = time.monotonic()
    r = run_cli("launch", "exp1", "--steps", "500", "--composed", "--out", blocker / "bag", env=env,
                timeout=120)
    assert r.returncode == 1, r.stderr[-2000:]
    assert "causal_arm_recorder failed" in r.stderr and str(blocker) in r.stderr, r.stderr[-2000:]
    assert time.monotonic() - start < 30, "the other nodes waited out their timeouts"


def test_composed_nodes_each_log_to_rosout_as_themselves(causal_arm_bin, tmp_path, private_netns):
    """Three nodes in one process: a CycloneDDS /rosout reader sees each node's lines under
    that node's name, also after the first of them (the babbler) has ended."""
    from cyclonedds.domain import DomainParticipant
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic
    from ros_idl import Log, ros_default_qos

    participant = DomainParticipant(28)
    reader = DataReader(participant, Topic(participant, "rt/rosout", Log), qos=ros_default_qos(1000))
    env = {**os.environ, "ROS_DOMAIN_ID": "28", "RUST_LOG": "info"}
    proc = subprocess.Popen([str(causal_arm_bin), "launch", "exp1", "--steps", "20000", "--composed",
                             "--out", str(tmp_path / "bag")], env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    lines = []
    while proc.poll() is None:
        lines += [(m.name, m.msg) for m in reader.take(N=100) if isinstance(m, Log)]
        time.sleep(0.05)
    time.sleep(0.5)
    lines += [(m.name, m.msg) for m in reader.take(N=1000) if isinstance(m, Log)]
    assert proc.returncode == 0, proc.stderr.read()[-2000:]
    said = {text.split()[0]: name for name, text in lines
            if text.startswith(("babbler answered", "simulator done", "wrote "))}
    assert said == {"babbler": "causal_arm_babbler", "simulator": "causal_arm_sim",
                    "wrote": "causal_arm_recorder"}, lines


def test_sigkill_of_the_launcher_stops_every_node_and_finalizes_the_bag(causal_arm_bin, tmp_path, private_netns):
    """The nodes get SIGTERM when their launcher dies, even by SIGKILL (PR_SET_PDEATHSIG):
    none outlives it, and the recorder finalizes the bag with whole steps."""
    env = {**os.environ, "ROS_DOMAIN_ID": "19", "RUST_LOG": "warn"}
    out = tmp_path / "orphaned"
    proc = subprocess.Popen([str(causal_arm_bin), "launch", "exp1", "--steps", "100000", "--seed", "1",
                             "--out", str(out)], env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and not any(out.glob("*.mcap")):
        time.sleep(0.2)
    time.sleep(2)
    children = [int(c) for c in pathlib.Path(f"/proc/{proc.pid}/task/{proc.pid}/children").read_text().split()]
    assert len(children) == 3, children
    proc.kill()
    proc.wait()
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline and any(pathlib.Path(f"/proc/{c}").exists() for c in children):
        time.sleep(0.1)
    alive = [c for c in children if pathlib.Path(f"/proc/{c}").exists()
             and "Z" not in pathlib.Path(f"/proc/{c}/stat").read_text().split()[2]]
    assert not alive, f"nodes outlived their launcher: {alive}"
    topics = read_bag(out)
    n = len(topics["/joint_states"])
    assert 0 < n < 100000
    for topic in STEP_TOPICS:
        assert len(topics[topic]) == n, topic


@pytest.mark.parametrize("victim", ["causal_arm_sim", "causal_arm_babbler", "causal_arm_recorder"])
def test_a_killed_node_ends_the_run_naming_it(causal_arm_bin, tmp_path, private_netns, victim):
    """SIGKILL of any node: the launcher notices within 2 s, stops the others, says which
    node died and how, exits non-zero, and leaves no node running."""
    env = {**os.environ, "ROS_DOMAIN_ID": "20", "RUST_LOG": "warn"}
    out = tmp_path / "faulted"
    proc = subprocess.Popen([str(causal_arm_bin), "launch", "exp1", "--steps", "100000", "--seed", "1",
                             "--out", str(out)], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and not any(out.glob("*.mcap")):
        time.sleep(0.2)
    time.sleep(2)
    children = [int(c) for c in pathlib.Path(f"/proc/{proc.pid}/task/{proc.pid}/children").read_text().split()]
    names = {c: pathlib.Path(f"/proc/{c}/comm").read_text().strip() for c in children}
    target = next(c for c, n in names.items() if victim.startswith(n))
    os.kill(target, signal.SIGKILL)
    killed_at = time.monotonic()
    try:
        _, stderr = proc.communicate(timeout=30)
    finally:
        proc.kill()
    exited = time.monotonic()
    assert proc.returncode != 0
    assert victim in stderr and "signal: 9" in stderr, stderr[-1500:]
    alive = [c for c in children if pathlib.Path(f"/proc/{c}").exists()
             and "Z" not in pathlib.Path(f"/proc/{c}/stat").read_text().split()[2]]
    assert not alive, f"nodes left running: {[names[c] for c in alive]}"
    # Noticed within 2 s; this bounds noticing, stopping the others and finalizing the bag.
    assert exited - killed_at < 5, exited - killed_at


def test_no_acknowledged_step_is_lost_when_the_recorder_is_killed(causal_arm_bin, run_cli, tmp_path,
                                                                  private_netns):
    """The recorder acknowledges a step on /recorder/ack only once its chunk is closed and
    handed to the OS: after a SIGKILL of the recorder, the bag (recovered from its crash
    tail) holds every step up to the last acknowledged one, each whole."""
    from cyclonedds.domain import DomainParticipant
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic
    from ros_idl import Clock, ros_default_qos

    participant = DomainParticipant(21)
    acks = DataReader(participant, Topic(participant, "rt/recorder/ack", Clock), qos=ros_default_qos(100))
    env = {**os.environ, "ROS_DOMAIN_ID": "21", "RUST_LOG": "warn"}
    out = tmp_path / "killed_recorder"
    proc = subprocess.Popen([str(causal_arm_bin), "launch", "exp1", "--steps", "100000", "--seed", "1",
                             "--out", str(out)], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and not any(out.glob("*.mcap")):
        time.sleep(0.2)
    acked = []
    until = time.monotonic() + 2.5
    while time.monotonic() < until:
        acked += [m.clock.sec * 10**9 + m.clock.nanosec for m in acks.take(N=100) if isinstance(m, Clock)]
        time.sleep(0.01)
    children = [int(c) for c in pathlib.Path(f"/proc/{proc.pid}/task/{proc.pid}/children").read_text().split()]
    recorder = next(c for c in children if pathlib.Path(f"/proc/{c}/comm").read_text().strip()
                    in "causal_arm_recorder")
    os.kill(recorder, signal.SIGKILL)
    try:
        proc.communicate(timeout=30)
    finally:
        proc.kill()
    # Acknowledgements already in flight were sent before the kill: they count too.
    acked += [m.clock.sec * 10**9 + m.clock.nanosec for m in acks.take(N=1000) if isinstance(m, Clock)]
    assert len(acked) >= 3, acked
    recovered = tmp_path / "recovered"
    r = run_cli("bag", "recover", out, "--out", recovered)
    assert r.returncode == 0, r.stderr
    topics = read_bag(recovered)
    stamps = [m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for _, m in topics["/joint_states"]]
    assert stamps == sorted(stamps) and max(stamps) >= max(acked), (max(stamps), max(acked))
    for topic in STEP_TOPICS:
        assert len(topics[topic]) == len(stamps), topic


@pytest.mark.parametrize("victim", ["causal_arm_recorder", "causal_arm_sim", "launcher", "composed"])
def test_a_killed_launch_resumes_into_the_bag_of_an_uninterrupted_run(causal_arm_bin, run_cli, tmp_path,
                                                                      private_netns, victim):
    """SIGKILL of a node (or of the launcher, or of the process holding the composed nodes)
    mid-run, then `launch --resume`: the bag ends equal to `generate` of the same seed, no
    step missing or duplicated."""
    composed = ["--composed"] if victim == "composed" else []
    # Composed nodes run several times faster: they are killed once a tenth of the bag
    # (about 1.5 MB of 14) is written, whatever this machine's speed.
    args = ["exp2", "--episodes", "40" if composed else "16", "--seed", "3"]
    env = {**os.environ, "ROS_DOMAIN_ID": "22", "RUST_LOG": "warn"}
    out = tmp_path / "resumed"
    proc = subprocess.Popen([str(causal_arm_bin), "launch", *args, *composed, "--out", str(out)], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and not any(out.glob("*.mcap")):
        time.sleep(0.2)
    if composed:
        while time.monotonic() < deadline and sum(f.stat().st_size for f in out.glob("*.mcap")) < 1_500_000:
            time.sleep(0.01)
    else:
        time.sleep(2.5)
    assert proc.poll() is None, "the run ended before the kill"
    children = [int(c) for c in pathlib.Path(f"/proc/{proc.pid}/task/{proc.pid}/children").read_text().split()]
    if victim in ("launcher", "composed"):
        proc.kill()
    else:
        os.kill(next(c for c in children if victim.startswith(pathlib.Path(f"/proc/{c}/comm").read_text().strip())),
                signal.SIGKILL)
    try:
        proc.communicate(timeout=30)
    finally:
        proc.kill()
    deadline = time.monotonic() + 15
    while time.monotonic() < deadline and any(pathlib.Path(f"/proc/{c}").exists() for c in children):
        time.sleep(0.1)
    r = run_cli("launch", *args, *composed, "--out", out, "--resume", env=env, timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    local = tmp_path / "local"
    assert run_cli("generate", *args, "--out", local).returncode == 0
    assert_same_bag(out, local, "differs from the uninterrupted run")


def test_generate_reports_progress_in_plain_lines_when_stderr_is_a_pipe(run_cli, tmp_path):
    """A bar cannot draw into a pipe or a log file: there, progress is plain lines."""
    r = run_cli("generate", "exp1", "--steps", "300", "--seed", "3", "--out", tmp_path / "bag")
    assert r.returncode == 0, r.stderr
    assert "exp1 seed 3: 300/300 steps (" in r.stderr, r.stderr
    assert "\x1b[" not in r.stderr and "\r" not in r.stderr, "terminal control codes in a pipe"


def test_a_killed_generate_resumes_into_the_bag_of_an_uninterrupted_run(causal_arm_bin, run_cli, tmp_path):
    args = ["exp1", "--steps", "150000", "--seed", "2"]
    out = tmp_path / "killed"
    proc = subprocess.Popen([str(causal_arm_bin), "generate", *args, "--out", str(out)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and sum(f.stat().st_size for f in out.glob("*.mcap")) < 3_000_000:
        time.sleep(0.05)
    proc.kill()
    proc.wait()
    r = run_cli("generate", *args, "--out", out, "--resume", timeout=600)
    assert r.returncode == 0 and "resumed at step" in r.stdout, r.stderr[-3000:]
    at = int(r.stdout.split("resumed at step ")[1].split(")")[0])
    assert 0 < at < 150000, r.stdout
    local = tmp_path / "local"
    assert run_cli("generate", *args, "--out", local, timeout=600).returncode == 0
    # Same messages, byte for byte, in the same order.
    from mcap.reader import make_reader
    def messages(bag):
        with open(next(pathlib.Path(bag).glob("*.mcap")), "rb") as f:
            return [(c.topic, m.log_time, m.data) for _, c, m in make_reader(f).iter_messages(log_time_order=False)]
    assert messages(out) == messages(local)
    r = run_cli("generate", *args, "--out", out, "--resume")
    assert r.returncode != 0 and "nothing to resume" in r.stderr, r.stderr[-2000:]


def test_player_republishes_a_bag(run_cli, causal_arm_bin, tmp_path, private_netns):
    bag = tmp_path / "small"
    assert run_cli("generate", "exp1", "--steps", "40", "--seed", "2", "--out", bag).returncode == 0
    env = {**os.environ, "ROS_DOMAIN_ID": "19", "RUST_LOG": "warn"}
    echo = subprocess.Popen([str(causal_arm_bin), "topic", "echo", "/joint_states", "--type",
                             "sensor_msgs/msg/JointState", "--count", "40", "--timeout", "60", "--qos", "recorded"],
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    time.sleep(1.0)
    r = run_cli("play", bag, "--rate", "0", "--delay", "2", "--topics", "/joint_states", env=env, timeout=120)
    assert r.returncode == 0, r.stderr
    out, err = echo.communicate(timeout=90)
    assert echo.returncode == 0, err
    got = [json.loads(line) for line in out.splitlines()]
    want = [m for _, m in read_bag(bag)["/joint_states"]]
    assert len(got) == 40
    for g, w in zip(got, want):
        assert g["position"] == list(w.position)
        assert g["header"]["stamp"] == {"sec": w.header.stamp.sec, "nanosec": w.header.stamp.nanosec}


def test_player_bad_input(run_cli, tmp_path, exp1_bag, private_netns):
    r = run_cli("play", tmp_path / "missing")
    assert r.returncode != 0 and "missing" in r.stderr
    r = run_cli("play", exp1_bag, "--topics", "/nope")
    assert r.returncode != 0 and "no topic /nope" in r.stderr


def test_sigkill_leaves_a_readable_prefix(causal_arm_bin, run_cli, tmp_path):
    out = tmp_path / "killed"
    proc = subprocess.Popen([str(causal_arm_bin), "generate", "exp1", "--steps", "3000000", "--out", str(out)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    mcap_file = out / "killed_0.mcap"
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and (not mcap_file.exists() or mcap_file.stat().st_size < 3_000_000):
        time.sleep(0.05)
    proc.kill()
    proc.wait()
    r = run_cli("bag", "info", out)
    assert r.returncode == 0, r.stderr
    info = json.loads(r.stdout)
    assert info["complete"] is False and info["truncation"], "killed before finishing"
    assert "incomplete" in r.stderr
    # metadata.yaml exists from the start, is kept current as chunks land (as rosbag2
    # does), and never counts more than the file holds.
    import yaml
    meta = yaml.safe_load((out / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert 20000 < meta["message_count"] <= info["message_count"], "the index was not kept current"
    counts = {t["name"]: t["message_count"] for t in info["topics"]}
    assert counts["/joint_states"] > 1000
    # Whole steps survive: every state topic of a step is in the same chunk as its action
    # or an earlier one, so counts differ by at most one step.
    assert max(counts[t] for t in STEP_TOPICS) - min(counts[t] for t in STEP_TOPICS) <= 1
    # An independent streaming reader gets the same prefix before hitting the cut.
    from mcap.records import Message
    from mcap.stream_reader import StreamReader

    seen = 0
    with open(mcap_file, "rb") as f:
        try:
            for record in StreamReader(f).records:
                seen += isinstance(record, Message)
        except Exception:  # the chunk being written when the process died
            pass
    assert seen == info["message_count"]
    # `bag recover` finishes it: the half step the kill cut is dropped, nothing else, and
    # rosbags (which refuses any MCAP file without its closing magic) reads the result.
    r = run_cli("bag", "recover", out, "--out", tmp_path / "finished")
    assert r.returncode == 0, r.stderr
    report = json.loads(r.stdout)
    assert 0 <= report["dropped_partial_last_stamp"] < len(STEP_TOPICS)
    assert report["recovered_messages"] + report["dropped_partial_last_stamp"] == info["message_count"]
    with AnyReader([tmp_path / "finished"]) as reader:
        assert sum(1 for _ in reader.messages()) == report["recovered_messages"]
    r = run_cli("bag", "check", tmp_path / "finished")
    assert r.returncode == 0, r.stdout[-800:] + r.stderr[-800:]


@pytest.mark.parametrize("distro,recorded", [("kilted", "kilted"), ("", "jazzy"), ("no such/distro", "jazzy")])
def test_the_bag_names_the_ros_distro_of_its_environment(run_cli, tmp_path, distro, recorded):
    import yaml

    out = tmp_path / "bag"
    r = run_cli("generate", "exp1", "--steps", "20", "--out", out, env={"ROS_DISTRO": distro})
    assert r.returncode == 0, r.stderr
    info = yaml.safe_load((out / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["ros_distro"] == recorded
