"""Rust nodes and CycloneDDS Python exchange /joint_states field-exact, both directions.

CycloneDDS is what rmw_cyclonedds_cpp uses, so this is the wire a ROS 2 user's rclpy node
would see. Runs only inside tests/netns-run (loopback only).
"""

import json
import os
import random
import subprocess
import time

import pytest
from cyclonedds.domain import DomainParticipant
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic

from ros_idl import Header, JointState, Time, ros_default_qos

JOINT_NAMES = [f"iiwa_joint_{i}" for i in range(1, 8)]
# Values chosen to catch lossy float handling: non-terminating binary fractions,
# subnormals, negative zero, large magnitudes.
POSITIONS = [0.1 + 0.2, -2.966999999999, 5e-324, -0.0, 1.0 / 3.0, 2.0 ** -30, 3.054]
VELOCITIES = [1e300, -1e-300, 0.5, -0.25, 1.483, 2.269, 2.356]
EFFORTS = [320.0, -320.0, 176.0, 110.0, 40.0, 40.000000000001, 0.0]


@pytest.fixture
def domain_id(private_netns):
    return random.randint(1, 200)


def _env(domain_id):
    return {**os.environ, "ROS_DOMAIN_ID": str(domain_id), "RUST_LOG": "warn"}


def _sample_json():
    return {
        "header": {"stamp": {"sec": 1234, "nanosec": 567890123}, "frame_id": "world ünïcode"},
        "name": JOINT_NAMES,
        "position": POSITIONS,
        "velocity": VELOCITIES,
        "effort": EFFORTS,
    }


def _same_float_bits(a, b):
    import struct

    return struct.pack("<d", a) == struct.pack("<d", b)


def _assert_joint_state_equal(got, want):
    assert got["header"]["stamp"] == want["header"]["stamp"]
    assert got["header"]["frame_id"] == want["header"]["frame_id"]
    assert got["name"] == want["name"]
    for key in ("position", "velocity", "effort"):
        assert len(got[key]) == len(want[key]), key
        for g, w in zip(got[key], want[key]):
            assert _same_float_bits(g, w), f"{key}: {g!r} != {w!r}"


def _as_dict(msg: JointState):
    return {
        "header": {
            "stamp": {"sec": msg.header.stamp.sec, "nanosec": msg.header.stamp.nanosec},
            "frame_id": msg.header.frame_id,
        },
        "name": list(msg.name),
        "position": list(msg.position),
        "velocity": list(msg.velocity),
        "effort": list(msg.effort),
    }


def test_rust_publisher_to_cyclonedds_subscriber(run_cli, causal_arm_bin, domain_id):
    participant = DomainParticipant(domain_id)
    topic = Topic(participant, "rt/joint_states", JointState)
    reader = DataReader(participant, topic, qos=ros_default_qos())
    want = _sample_json()
    proc = subprocess.Popen(
        [str(causal_arm_bin), "topic", "pub", "/joint_states", "--type", "sensor_msgs/msg/JointState",
         "--json", json.dumps(want), "--count", "3", "--rate", "20", "--wait-subscribers", "1",
         "--timeout", "30"],
        env=_env(domain_id), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )
    received = []
    deadline = time.monotonic() + 40
    while len(received) < 3 and time.monotonic() < deadline:
        received.extend(s for s in reader.take(N=10) if isinstance(s, JointState))
        time.sleep(0.01)
    out, err = proc.communicate(timeout=30)
    assert proc.returncode == 0, err
    assert len(received) == 3, f"received {len(received)} samples; publisher stderr: {err}"
    for msg in received:
        _assert_joint_state_equal(_as_dict(msg), want)


def test_cyclonedds_publisher_to_rust_subscriber(causal_arm_bin, domain_id):
    participant = DomainParticipant(domain_id)
    topic = Topic(participant, "rt/joint_states", JointState)
    writer = DataWriter(participant, topic, qos=ros_default_qos())
    want = _sample_json()
    sample = JointState(
        header=Header(stamp=Time(sec=1234, nanosec=567890123), frame_id=want["header"]["frame_id"]),
        name=JOINT_NAMES, position=POSITIONS, velocity=VELOCITIES, effort=EFFORTS,
    )
    proc = subprocess.Popen(
        [str(causal_arm_bin), "topic", "echo", "/joint_states", "--type", "sensor_msgs/msg/JointState",
         "--count", "1", "--timeout", "40"],
        env=_env(domain_id), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )
    # Keep publishing until the Rust side has matched and printed one sample.
    deadline = time.monotonic() + 45
    while proc.poll() is None and time.monotonic() < deadline:
        writer.write(sample)
        time.sleep(0.05)
    out, err = proc.communicate(timeout=10)
    assert proc.returncode == 0, err
    lines = [line for line in out.splitlines() if line.strip()]
    assert len(lines) == 1, out
    _assert_joint_state_equal(json.loads(lines[0]), want)


def test_invalid_domain_id_is_rejected(run_cli, private_netns):
    result = run_cli("topic", "echo", "/joint_states", "--type", "sensor_msgs/msg/JointState",
                     "--count", "1", env={"ROS_DOMAIN_ID": "abc"}, timeout=30)
    assert result.returncode != 0
    assert 'ROS_DOMAIN_ID="abc"' in result.stderr
    assert "0 to 232" in result.stderr


def test_unknown_parameter_is_rejected(run_cli, private_netns):
    result = run_cli("topic", "echo", "/joint_states", "--type", "sensor_msgs/msg/JointState",
                     "--count", "1", "--ros-args", "-p", "no_such_param:=3", timeout=30)
    assert result.returncode != 0
    assert 'unknown parameter "no_such_param"' in result.stderr
    assert "use_sim_time" in result.stderr  # lists what is declared


def test_unknown_message_type_is_rejected(run_cli, private_netns):
    result = run_cli("topic", "echo", "/x", "--type", "sensor_msgs/msg/JointStat", timeout=30)
    assert result.returncode != 0
    assert "sensor_msgs/msg/JointStat" in result.stderr

