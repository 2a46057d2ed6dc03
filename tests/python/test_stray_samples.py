"""Any ROS 2 node may publish on the graph's topics. A stray or malformed sample must
neither end a run nor enter the bag: CycloneDDS participants flood a running `launch` with
short, NaN and old-stamped actions and joint states, and with well-formed ones of the very
step being run (duplicates that would take the real sample's place), one participant
announcing itself as a ROS 2 node on ros_discovery_info as rmw does, the other not at all.
A forged /recorder/ack is screened like the data (another node's writer is ignored) and,
from a writer claiming the recorder's name, refused when it acknowledges steps not yet
published. The bag must still hold
every step, identical to the in-process run of the same seed."""

import math
import re
import os
import subprocess
import time

from test_datagen import assert_same_bag

STEP_NS = 1e9 / 24  # dt × substeps of the default simulator


def stamp_of(k: int):
    from ros_idl import Time
    ns = round(k * STEP_NS)
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def strays(k: int):
    """For step k: malformed actions and joint states, well-formed ones with old stamps
    (stale), and well-formed ones of step k itself (duplicates of the real ones, with
    other values)."""
    from ros_idl import Action, Header, JointState
    names = [f"iiwa_joint_{i}" for i in range(1, 8)]
    now, old = Header(stamp=stamp_of(k)), Header(stamp=stamp_of(0))
    bad_actions = [
        Action(header=now, joint_deltas=[0.0] * 3, joint_targets=[0.1] * 3),
        Action(header=now, joint_deltas=[0.0] * 7, joint_targets=[math.nan] + [0.1] * 6),
        Action(header=now, joint_deltas=[0.0] * 7, joint_targets=[0.1] * 7, magnet=9),
        Action(header=old, joint_deltas=[0.0] * 7, joint_targets=[0.1] * 7),
    ]
    bad_states = [
        JointState(header=now, name=names[:3], position=[0.0] * 3, velocity=[0.0] * 3, effort=[0.0] * 3),
        JointState(header=now, name=names, position=[math.inf] * 7, velocity=[0.0] * 7, effort=[0.0] * 7),
        JointState(header=old, name=names, position=[0.0] * 7, velocity=[0.0] * 7, effort=[0.0] * 7),
    ]
    duplicates = (
        [Action(header=now, joint_deltas=[0.0] * 7, joint_targets=[0.1] * 7)],
        [JointState(header=now, name=names, position=[0.3] * 7, velocity=[0.0] * 7, effort=[0.0] * 7)],
    )
    return (bad_actions, bad_states), duplicates


def announce(participant, nodes):
    """Publishes `participant`'s ros_discovery_info as rmw does: `nodes` maps a node name to
    the writers it owns. Returns the writer, which must live as long as the announcement."""
    from cyclonedds.pub import DataWriter
    from cyclonedds.topic import Topic
    from ros_idl import NodeEntitiesInfo, ParticipantEntitiesInfo, discovery_info_qos, gid_of
    writer = DataWriter(participant, Topic(participant, "ros_discovery_info", ParticipantEntitiesInfo),
                        qos=discovery_info_qos())
    writer.write(ParticipantEntitiesInfo(gid=gid_of(participant), node_entities_info_seq=[
        NodeEntitiesInfo(node_namespace="/", node_name=name, writer_gid_seq=[gid_of(w) for w in owned])
        for name, owned in nodes.items()]))
    return writer


def test_stray_and_malformed_samples_neither_stop_the_run_nor_enter_the_bag(
        run_cli, causal_arm_bin, tmp_path, private_netns):
    from cyclonedds.domain import DomainParticipant
    from cyclonedds.pub import DataWriter
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic
    from ros_idl import Action, Clock, JointState, ros_default_qos

    steps, domain = 3000, 23

    def writers_of(p):
        return (DataWriter(p, Topic(p, "rt/babbler/action", Action), qos=ros_default_qos(100)),
                DataWriter(p, Topic(p, "rt/joint_states", JointState), qos=ros_default_qos(100)))

    # Three stray participants: a plain DDS program (never announced); the ROS 2 node
    # /impostor, announced as every rmw does; and one whose nodes take the graph's own
    # names (a name proves nothing, so its malformed, NaN and stale samples reach the
    # nodes' sample checks; it sends no well-formed duplicates, which only SROS2 could
    # keep out).
    plain, impostor, namesake = (DomainParticipant(domain) for _ in range(3))
    plain_w, impostor_w, namesake_w = writers_of(plain), writers_of(impostor), writers_of(namesake)

    def ack_writer(p):
        return DataWriter(p, Topic(p, "rt/recorder/ack", Clock), qos=ros_default_qos(100))

    # Forged recorder acknowledgements of steps far ahead: taken, they would let the
    # simulator run away from the recorder. The plain program's wait unannounced, the
    # impostor's are another node's, the namesake's pass the writer check (it announces
    # a "causal_arm_recorder") and are refused as acknowledging unpublished steps.
    forged_acks = [ack_writer(p) for p in (plain, impostor, namesake)]
    announcements = [
        announce(impostor, {"impostor": [*impostor_w, forged_acks[1]]}),
        announce(namesake, {"causal_arm_babbler": namesake_w[:1], "causal_arm_sim": namesake_w[1:],
                            "causal_arm_recorder": [forged_acks[2]]}),
    ]
    state_reader = DataReader(plain, Topic(plain, "rt/joint_states", JointState), qos=ros_default_qos(100))
    env = {**os.environ, "ROS_DOMAIN_ID": str(domain), "RUST_LOG": "warn,causal_arm_rig=info"}
    dds = tmp_path / "dds"
    proc = subprocess.Popen([str(causal_arm_bin), "launch", "exp1", "--steps", str(steps), "--seed", "4",
                             "--out", str(dds)], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    # Wait until the run is past its first second of sim time, then flood it.
    latest, deadline = 0, time.monotonic() + 120
    while latest < 24 and time.monotonic() < deadline and proc.poll() is None:
        for m in state_reader.take(N=100):
            if isinstance(m, JointState):
                latest = max(latest, round((m.header.stamp.sec * 1e9 + m.header.stamp.nanosec) / STEP_NS))
        time.sleep(0.01)
    assert latest >= 24, "the graph did not start"
    sent = 0
    for k in range(latest, steps, 7):
        bad, duplicates = strays(k)
        for (action_writer, state_writer), kinds in ((plain_w, (bad, duplicates)), (impostor_w, (bad, duplicates)),
                                                      (namesake_w, (bad,))):
            for actions, states in kinds:
                for a in actions:
                    action_writer.write(a)
                for s in states:
                    state_writer.write(s)
                sent += len(actions) + len(states)
        for forged in forged_acks:
            forged.write(Clock(clock=stamp_of(k + 10_000)))
        if proc.poll() is not None:
            break
        time.sleep(0.002)
    stdout, stderr = proc.communicate(timeout=600)
    assert len(announcements) == 2
    assert sent > 100
    assert proc.returncode == 0, stderr[-3000:]
    assert f"({steps} of {steps} steps over DDS" in stdout, stdout
    # The namesake's samples pass the writer check and are refused as malformed or stale.
    assert "ignoring an action" in stderr and "malformed" in stderr, stderr[-3000:]
    assert "ignoring an acknowledgement of step" in stderr, stderr[-3000:]
    foreign_acks = re.search(r"(\d+) acknowledgements of other nodes' writers", stderr)
    assert foreign_acks and int(foreign_acks[1]) > 0, stderr[-3000:]
    # The impostor's are refused by writer, in all three nodes, and the plain program's
    # wait unannounced (then are dropped as the quarantine fills).
    summaries = [line for line in stderr.splitlines() if "of other nodes' writers" in line]
    for node in ("simulator done", "babbler answered", "recorder ignored"):
        line = next((line for line in summaries if node in line), None)
        foreign = re.search(r"ignored (\d+) (?:samples|actions) of other nodes' writers, (\d+) of unannounced",
                            line or "")
        assert foreign and int(foreign[1]) > 0 and int(foreign[2]) > 0, (node, summaries)
    local = tmp_path / "local"
    r = run_cli("generate", "exp1", "--steps", str(steps), "--seed", "4", "--out", local)
    assert r.returncode == 0, r.stderr
    assert_same_bag(dds, local, "differs from the in-process run")


def test_a_composed_graph_takes_its_own_topics_from_its_own_nodes_only(run_cli, causal_arm_bin, tmp_path,
                                                                        private_netns):
    """Composed in one process, the nodes hand each other the step's topics in process and
    read none of them from DDS: even well-formed samples of the very step being run, from a
    participant announcing the graph's own node names (which a graph of processes can only
    keep out with SROS2), and acknowledgements of steps far ahead never reach the bag or the
    simulator's window. The bag equals the in-process run of the seed."""
    from cyclonedds.domain import DomainParticipant
    from cyclonedds.pub import DataWriter
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic
    from ros_idl import Action, Clock, JointState, ros_default_qos

    steps, domain = 6000, 29
    namesake = DomainParticipant(domain)
    actions = DataWriter(namesake, Topic(namesake, "rt/babbler/action", Action), qos=ros_default_qos(100))
    states = DataWriter(namesake, Topic(namesake, "rt/joint_states", JointState), qos=ros_default_qos(100))
    acks = DataWriter(namesake, Topic(namesake, "rt/recorder/ack", Clock), qos=ros_default_qos(100))
    announcement = announce(namesake, {"causal_arm_babbler": [actions], "causal_arm_sim": [states],
                                       "causal_arm_recorder": [acks]})
    # The graph's states, read on a participant of their own (the namesake's reader would
    # also get the namesake's forged ones).
    watcher = DomainParticipant(domain)
    state_reader = DataReader(watcher, Topic(watcher, "rt/joint_states", JointState), qos=ros_default_qos(100))
    env = {**os.environ, "ROS_DOMAIN_ID": str(domain), "RUST_LOG": "warn"}
    dds = tmp_path / "composed"
    proc = subprocess.Popen([str(causal_arm_bin), "launch", "exp1", "--steps", str(steps), "--seed", "4",
                             "--composed", "--out", str(dds)], env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    sent, latest, deadline = 0, 0, time.monotonic() + 120
    while proc.poll() is None and time.monotonic() < deadline:
        for m in state_reader.take(N=100):
            if isinstance(m, JointState):
                latest = max(latest, round((m.header.stamp.sec * 1e9 + m.header.stamp.nanosec) / STEP_NS))
        # Duplicates of the steps just published and the next ones, with other values.
        for k in range(latest, latest + 8):
            (dup_actions, dup_states) = strays(k)[1]
            for a in dup_actions:
                actions.write(a)
            for s in dup_states:
                states.write(s)
            acks.write(Clock(clock=stamp_of(k + 10_000)))
            sent += 3
        time.sleep(0.002)
    stdout, stderr = proc.communicate(timeout=120)
    assert announcement is not None
    assert latest > 0 and sent > 100, (latest, sent)
    assert proc.returncode == 0, stderr[-3000:]
    assert f"({steps} of {steps} steps by nodes composed in one process" in stdout, stdout
    local = tmp_path / "local"
    r = run_cli("generate", "exp1", "--steps", str(steps), "--seed", "4", "--out", local)
    assert r.returncode == 0, r.stderr
    assert_same_bag(dds, local, "differs from the in-process run")
