"""Any ROS 2 node may publish on the graph's topics. A stray or malformed sample must
neither end a run nor enter the bag: a CycloneDDS participant floods a running `launch` with
short, NaN and old-stamped actions and joint states, and the bag must still hold every step,
identical to the in-process run of the same seed."""

import math
import os
import subprocess
import time

from test_datagen import _canonical

STEP_NS = 1e9 / 24  # dt × substeps of the default simulator


def stamp_of(k: int):
    from ros_idl import Time
    ns = round(k * STEP_NS)
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def strays(k: int):
    """Malformed actions and joint states for step k, and well-formed ones with old stamps."""
    from ros_idl import Action, Header, JointState
    names = [f"iiwa_joint_{i}" for i in range(1, 8)]
    now, old = Header(stamp=stamp_of(k)), Header(stamp=stamp_of(0))
    actions = [
        Action(header=now, joint_deltas=[0.0] * 3, joint_targets=[0.1] * 3),
        Action(header=now, joint_deltas=[0.0] * 7, joint_targets=[math.nan] + [0.1] * 6),
        Action(header=now, joint_deltas=[0.0] * 7, joint_targets=[0.1] * 7, magnet=9),
        Action(header=old, joint_deltas=[0.0] * 7, joint_targets=[0.1] * 7),
    ]
    states = [
        JointState(header=now, name=names[:3], position=[0.0] * 3, velocity=[0.0] * 3, effort=[0.0] * 3),
        JointState(header=now, name=names, position=[math.inf] * 7, velocity=[0.0] * 7, effort=[0.0] * 7),
        JointState(header=old, name=names, position=[0.0] * 7, velocity=[0.0] * 7, effort=[0.0] * 7),
    ]
    return actions, states


def test_stray_and_malformed_samples_neither_stop_the_run_nor_enter_the_bag(
        run_cli, causal_arm_bin, tmp_path, private_netns):
    from cyclonedds.domain import DomainParticipant
    from cyclonedds.pub import DataWriter
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic
    from ros_idl import Action, JointState, ros_default_qos

    steps, domain = 3000, 23
    participant = DomainParticipant(domain)
    action_writer = DataWriter(participant, Topic(participant, "rt/babbler/action", Action), qos=ros_default_qos(100))
    state_writer = DataWriter(participant, Topic(participant, "rt/joint_states", JointState), qos=ros_default_qos(100))
    state_reader = DataReader(participant, Topic(participant, "rt/joint_states", JointState), qos=ros_default_qos(100))
    env = {**os.environ, "ROS_DOMAIN_ID": str(domain), "RUST_LOG": "warn"}
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
        actions, states = strays(k)
        for a in actions:
            action_writer.write(a)
        for s in states:
            state_writer.write(s)
        sent += len(actions) + len(states)
        if proc.poll() is not None:
            break
        time.sleep(0.002)
    stdout, stderr = proc.communicate(timeout=600)
    assert sent > 100
    assert proc.returncode == 0, stderr[-3000:]
    assert f"({steps} of {steps} steps over DDS" in stdout, stdout
    assert "ignoring an action" in stderr and "malformed" in stderr, stderr[-3000:]
    local = tmp_path / "local"
    r = run_cli("generate", "exp1", "--steps", str(steps), "--seed", "4", "--out", local)
    assert r.returncode == 0, r.stderr
    a, b = _canonical(dds), _canonical(local)
    assert a.keys() == b.keys()
    for topic in a:
        assert a[topic] == b[topic], f"{topic} differs from the in-process run"
