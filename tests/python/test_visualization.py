"""What a viewer (RViz, Foxglove, Lichtblick) needs from a bag, checked with independent
readers:
- the tf tree against PyBullet: /tf_static (fixed joints, table) and /tf (every revolute
  joint, the cube) composed link by link equal PyBullet's link frames for the same URDF and
  the recorded joint angles, and every frame has exactly one parent, as with
  robot_state_publisher beside a simulator (rosbags reads the messages, PyBullet places the
  links: neither is our code);
- the scene markers, decoded by mcap-ros2 from the bag's own schema, show each step's cube
  colour and magnet state in frames the tf tree has;
- the committed Foxglove layout names only topics, fields and frames the bag has."""

import json
import pathlib
import re

import numpy as np
import pybullet as p
import pytest
from rosbags.highlevel import AnyReader

from test_kinematics_oracle import _angle_between

STEPS_CHECKED = 200


@pytest.fixture(scope="module")
def exp2_bag(run_cli, tmp_path_factory):
    out = tmp_path_factory.mktemp("tf") / "exp2"
    r = run_cli("generate", "exp2", "--episodes", "1", "--seed", "4", "--out", out, timeout=300)
    assert r.returncode == 0, r.stderr
    return out


def _read(bag):
    """topic -> [(log_time, message)], decoded by rosbags from the bag's own schemas."""
    out = {}
    with AnyReader([pathlib.Path(bag)]) as reader:
        for conn, t, raw in reader.messages():
            out.setdefault(conn.topic, []).append((t, reader.deserialize(raw, conn.msgtype)))
    return out


def _pose(transform):
    t, r = transform.translation, transform.rotation
    return np.array([t.x, t.y, t.z]), np.array([r.x, r.y, r.z, r.w])


def _edges(tf_message):
    return [(t.header.frame_id, t.child_frame_id, _pose(t.transform)) for t in tf_message.transforms]


def _compose(edges, root="world"):
    """World pose (position, xyzw) of every frame reachable from `root`, in float64."""
    from scipy.spatial.transform import Rotation as R

    world = {root: (np.zeros(3), R.identity())}
    pending = list(edges)
    while pending:
        progress = [e for e in pending if e[0] in world]
        assert progress, f"frames not connected to {root}: {[e[1] for e in pending]}"
        for parent, child, (pos, quat) in progress:
            wp, wr = world[parent]
            world[child] = (wp + wr.apply(pos), wr * R.from_quat(quat))
        pending = [e for e in pending if e[1] not in world]
    return {k: (v[0], v[1].as_quat()) for k, v in world.items()}


@pytest.fixture(scope="module")
def pybullet_arm(repo_root):
    client = p.connect(p.DIRECT)
    robot = p.loadURDF(str(repo_root / "urdf" / "iiwa14_magnet.urdf"), useFixedBase=True,
                       physicsClientId=client)
    table = p.loadURDF(str(repo_root / "urdf" / "table.urdf"), useFixedBase=True, physicsClientId=client)
    links, revolute = {}, {}
    for j in range(p.getNumJoints(robot, physicsClientId=client)):
        info = p.getJointInfo(robot, j, physicsClientId=client)
        links[info[12].decode()] = j
        if info[2] == p.JOINT_REVOLUTE:
            revolute[info[1].decode()] = j
    yield client, robot, table, links, revolute
    p.disconnect(client)


def test_every_frame_has_one_parent_and_the_static_part_is_latched(exp2_bag):
    topics = _read(exp2_bag)
    (t0, static), = topics["/tf_static"]
    assert t0 == 0
    static_edges = _edges(static)
    assert {c for _, c, _ in static_edges} == {"iiwa_link_0", "magnet", "ef", "table_top"}
    tf = topics["/tf"]
    assert len(tf) == 500, "one /tf per step"
    for _, msg in tf:
        children = [c for _, c, _ in static_edges] + [c for _, c, _ in _edges(msg)]
        assert len(children) == len(set(children)), f"a frame with two parents: {sorted(children)}"
        assert sorted(children) == sorted(["iiwa_link_0", "magnet", "ef", "table_top", "object"]
                                          + [f"iiwa_link_{i}" for i in range(1, 8)])
    import yaml

    meta = yaml.safe_load((pathlib.Path(exp2_bag) / "metadata.yaml").read_text())
    (entry,) = [t["topic_metadata"] for t in meta["rosbag2_bagfile_information"]["topics_with_message_count"]
                if t["topic_metadata"]["name"] == "/tf_static"]
    assert entry["type"] == "tf2_msgs/msg/TFMessage"
    assert entry["offered_qos_profiles"][0]["durability"] == "transient_local", "latched, as tf_static is"


def test_the_composed_tf_chain_equals_pybullet_link_poses(exp2_bag, pybullet_arm):
    client, robot, table, links, revolute = pybullet_arm
    topics = _read(exp2_bag)
    static_edges = _edges(topics["/tf_static"][0][1])
    joint_states = {t: m for t, m in topics["/joint_states"]}
    ef_poses = {t: m for t, m in topics["/end_effector/pose"]}
    object_poses = {t: m for t, m in topics["/object/pose"]}
    tf = topics["/tf"]
    picked = np.linspace(0, len(tf) - 1, STEPS_CHECKED).round().astype(int)
    worst_pos, worst_rot, checked = 0.0, 0.0, 0
    for i in picked:
        t, msg = tf[i]
        js = joint_states[t]
        for name, q in zip(js.name, js.position):
            p.resetJointState(robot, revolute[name], float(q), physicsClientId=client)
        world = _compose(static_edges + _edges(msg))
        for link, j in links.items():
            state = p.getLinkState(robot, j, computeForwardKinematics=True, physicsClientId=client)
            pos, quat = world[link]
            worst_pos = max(worst_pos, float(np.max(np.abs(pos - np.array(state[4])))))
            worst_rot = max(worst_rot, _angle_between(quat, state[5]))
            checked += 1
        # The tf tree agrees with the pose topics the dataset reads.
        ef = ef_poses[t].pose
        assert np.allclose(world["ef"][0], [ef.position.x, ef.position.y, ef.position.z], atol=1e-9)
        obj = object_poses[t].pose
        assert np.allclose(world["object"][0], [obj.position.x, obj.position.y, obj.position.z], atol=1e-12)
    assert checked == STEPS_CHECKED * len(links) and len(links) == 10
    print(f"tf chain vs PyBullet over {checked} link poses: {worst_pos:.2e} m, {worst_rot:.2e} rad")
    assert worst_pos < 1e-6 and worst_rot < 1e-6, (worst_pos, worst_rot)
    top = p.getLinkState(table, 0, physicsClientId=client)[4]
    (table_edge,) = [e for e in static_edges if e[1] == "table_top"]
    assert table_edge[0] == "world" and np.allclose(table_edge[2][0], top, atol=1e-6)


def test_scene_markers_show_each_steps_cube_colour_and_magnet(exp2_bag):
    from mcap_ros2.reader import read_ros2_messages

    topics = _read(exp2_bag)
    colours = {t: m.color for t, m in topics["/object/color"]}
    magnets = {t: m for t, m in topics["/magnet/state"]}
    (mcap_file,) = pathlib.Path(exp2_bag).glob("*.mcap")
    arrays = [(m.log_time_ns, m.ros_msg) for m in read_ros2_messages(str(mcap_file), topics=["/scene/markers"])]
    assert len(arrays) == 500, "one array per step"
    tf_frames = {"world"} | {t.child_frame_id for _, msg in topics["/tf_static"] + topics["/tf"][:1]
                             for t in msg.transforms}
    labels = set()
    for t, array in arrays:
        by_ns = {(k.ns, k.id): k for k in array.markers}
        assert set(by_ns) == {("table", 0), ("object", 0), ("magnet", 0), ("magnet", 1)}
        assert all(k.header.frame_id in tf_frames and k.frame_locked for k in array.markers)
        cube, c = by_ns[("object", 0)], colours[t]
        assert (cube.type, cube.color.r, cube.color.g, cube.color.b) == (1, c.r, c.g, c.b)
        assert cube.scale.x == cube.scale.y == cube.scale.z == 0.05
        table = by_ns[("table", 0)]
        assert (table.header.frame_id, table.scale.x, table.scale.y) == ("table_top", 0.4, 0.6)
        mag = magnets[t]
        want = "holding" if mag.holding else "on" if mag.on else "off"
        assert by_ns[("magnet", 1)].text == f"magnet: {want}"
        labels.add(want)
    assert labels == {"off", "on", "holding"}, "the episode switches the magnet and picks the cube"


def _resolve(message, path):
    """The value at a Foxglove message path tail such as `.pose.position.z` or `.position[3]`."""
    value = message
    for name, index in re.findall(r"\.(\w+)(?:\[(\d+)\])?", path):
        value = getattr(value, name)
        if index:
            value = value[int(index)]
    return value


def test_the_foxglove_layout_names_what_the_bag_has(exp2_bag, repo_root):
    layout = json.loads((repo_root / "docs" / "foxglove" / "causal_arm.json").read_text())
    topics = _read(exp2_bag)
    panels = layout["configById"]

    def placed(node):
        return [node] if isinstance(node, str) else placed(node["first"]) + placed(node["second"])

    assert sorted(placed(layout["layout"])) == sorted(panels), "every panel is placed, once"
    scene = panels["3D!scene"]
    urdf = [layer for layer in scene["layers"].values() if layer["layerId"] == "foxglove.Urdf"]
    assert [(u["sourceType"], u["topic"]) for u in urdf] == [("topic", "/robot_description")]
    assert topics["/robot_description"][0][1].data.startswith("<?xml")
    for topic in scene["topics"]:
        assert topic in topics, topic
    assert scene["followTf"] == "world"
    plotted = 0
    for panel_id, config in panels.items():
        if not panel_id.startswith("Plot!"):
            continue
        for entry in config["paths"]:
            topic, tail = re.match(r"(/[\w/]+?)(\..*)$", entry["value"]).groups()
            assert topic in topics, entry["value"]
            value = _resolve(topics[topic][0][1], tail)
            assert isinstance(value, (int, float, bool, np.number)), (entry["value"], value)
            plotted += 1
    assert plotted == 7 + 8 + 3
