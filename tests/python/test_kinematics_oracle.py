"""Our kinematics against PyBullet on the same URDF file, and the CLI's error messages.

PyBullet is an independent URDF loader and FK implementation, so agreement to 1e-6 on
1,000 random in-limit configurations shows the arm model (origins, rpy convention, axes,
fixed tool frames) is read correctly. PyBullet works in single precision (≈6e-8 m, ≈6e-7 rad
of float32 rounding), so a plain float64 numpy FK of the XML checks the last digits (1e-12).
IK solutions are verified with PyBullet's FK, and the URDF files themselves (table, cube,
collision model without gaps) are checked as PyBullet loads them.
"""

import json

import numpy as np
import pybullet as p
import pytest

LIMITS = np.array([2.967, 2.094, 2.967, 2.094, 2.967, 2.094, 3.054])


@pytest.fixture(scope="module")
def urdf_path(repo_root):
    return repo_root / "urdf" / "iiwa14_magnet.urdf"


@pytest.fixture(scope="module")
def bullet(urdf_path):
    client = p.connect(p.DIRECT)
    robot = p.loadURDF(str(urdf_path), useFixedBase=True, physicsClientId=client)
    joints, ef = [], None
    for j in range(p.getNumJoints(robot, physicsClientId=client)):
        info = p.getJointInfo(robot, j, physicsClientId=client)
        if info[2] == p.JOINT_REVOLUTE:
            joints.append(j)
        if info[12].decode() == "ef":
            ef = j
    assert len(joints) == 7 and ef is not None
    yield client, robot, joints, ef
    p.disconnect(client)


def _angle_between(q1, q2):
    """Rotation angle between two xyzw quaternions, accurate near zero
    (2·acos(|q1·q2|) loses precision there: acos(1-ε) ≈ √(2ε))."""
    q1 = np.asarray(q1, dtype=float) / np.linalg.norm(q1)
    q2 = np.asarray(q2, dtype=float) / np.linalg.norm(q2)
    if np.dot(q1, q2) < 0:
        q2 = -q2
    # atan2(|q1-q2|, |q1+q2|) is a quarter of the rotation angle.
    return 4.0 * np.arctan2(np.linalg.norm(q1 - q2), np.linalg.norm(q1 + q2))


def _fk_differences(run_cli, bullet, urdf, seed):
    """Max position and orientation differences between `causal-arm fk --batch --urdf URDF`
    and PyBullet (with the robot of `bullet`) over 1,000 random in-limit configurations."""
    client, robot, joints, ef = bullet
    rng = np.random.default_rng(seed)
    configs = rng.uniform(-LIMITS, LIMITS, size=(1000, 7))
    stdin = "\n".join(",".join(repr(float(v)) for v in q) for q in configs) + "\n"
    result = run_cli("fk", "--batch", "--urdf", urdf, input=stdin)
    assert result.returncode == 0, result.stderr
    ours = [json.loads(line) for line in result.stdout.splitlines()]
    assert len(ours) == 1000
    max_pos, max_rot = 0.0, 0.0
    for q, mine in zip(configs, ours):
        for j, v in zip(joints, q):
            p.resetJointState(robot, j, float(v), physicsClientId=client)
        # Index 4/5: world position/orientation of the URDF link frame (not the COM frame).
        state = p.getLinkState(robot, ef, computeForwardKinematics=True, physicsClientId=client)
        pos, orn = np.array(state[4]), np.array(state[5])
        max_pos = max(max_pos, float(np.max(np.abs(pos - mine["position"]))))
        max_rot = max(max_rot, _angle_between(orn, np.array(mine["orientation_xyzw"])))
    return max_pos, max_rot


def test_fk_matches_pybullet_on_1000_configurations(run_cli, bullet, urdf_path):
    max_pos, max_rot = _fk_differences(run_cli, bullet, urdf_path, seed=2024)
    print(f"FK vs PyBullet over 1000 configs: max |dp| = {max_pos:.3e} m, max angle = {max_rot:.3e} rad")
    assert max_pos <= 1e-6
    assert max_rot <= 1e-6


def _reference_fk(urdf_text, q):
    """Plain float64 FK in numpy, straight from the URDF XML: world → ef through every joint,
    T = T_parent · Trans(xyz) · Rz(yaw) Ry(pitch) Rx(roll) · Rot(axis, q)."""
    import xml.etree.ElementTree as ET

    def rot(axis, angle):
        axis = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
        k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
        return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k

    root = ET.fromstring(urdf_text)
    by_child = {j.find("child").get("link"): j for j in root.findall("joint")}
    chain, link = [], "ef"
    while link in by_child:
        chain.append(by_child[link])
        link = by_child[link].find("parent").get("link")
    t = np.eye(4)
    q = iter(q)
    for joint in reversed(chain):
        origin = joint.find("origin")
        xyz = [float(v) for v in origin.get("xyz", "0 0 0").split()]
        r, pi, y = [float(v) for v in origin.get("rpy", "0 0 0").split()]
        step = np.eye(4)
        step[:3, :3] = rot([0, 0, 1], y) @ rot([0, 1, 0], pi) @ rot([1, 0, 0], r)
        step[:3, 3] = xyz
        t = t @ step
        if joint.get("type") == "revolute":
            motion = np.eye(4)
            motion[:3, :3] = rot([float(v) for v in joint.find("axis").get("xyz").split()], next(q))
            t = t @ motion
    return t


def test_fk_matches_float64_reference_to_1e12(run_cli, urdf_path):
    """PyBullet computes in single precision (its link positions are float32 values, e.g.
    0.1574999988 for 0.1575), which is where the ≈6e-8 m / ≈6e-7 rad above come from. A plain
    float64 numpy FK of the same XML must agree with ours to rounding error."""
    text = urdf_path.read_text()
    configs = np.random.default_rng(3).uniform(-LIMITS, LIMITS, size=(200, 7))
    stdin = "\n".join(",".join(repr(float(v)) for v in q) for q in configs) + "\n"
    result = run_cli("fk", "--batch", input=stdin)
    assert result.returncode == 0, result.stderr
    max_pos = max_rot = 0.0
    for q, line in zip(configs, result.stdout.splitlines()):
        mine = json.loads(line)
        t = _reference_fk(text, q)
        max_pos = max(max_pos, float(np.max(np.abs(t[:3, 3] - mine["position"]))))
        x, y, z, w = mine["orientation_xyzw"]
        r_mine = np.array([
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ])
        max_rot = max(max_rot, float(np.max(np.abs(r_mine - t[:3, :3]))))
    print(f"FK vs float64 numpy reference over 200 configs: max |dp| = {max_pos:.3e} m, "
          f"max |dR| = {max_rot:.3e}")
    assert max_pos <= 1e-12
    assert max_rot <= 1e-12


def test_fk_single_configuration_output(run_cli):
    result = run_cli("fk", "--joints", "0,0,0,0,0,0,0")
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert len(lines) == 1
    out = json.loads(lines[0])
    assert list(out) == ["position", "orientation_xyzw"]
    # Straight up: the sum of the z offsets, 1.256 m to the flange + 0.1 m magnet tool.
    assert np.allclose(out["position"], [0.0, 0.0, 1.356], atol=1e-12)
    assert _angle_between(out["orientation_xyzw"], [0, 0, 0, 1]) < 1e-12


def test_ik_reaches_1000_reachable_targets(run_cli, bullet):
    client, robot, joints, ef = bullet
    rng = np.random.default_rng(7)
    targets = []
    for q in rng.uniform(-LIMITS, LIMITS, size=(1000, 7)):
        for j, v in zip(joints, q):
            p.resetJointState(robot, j, float(v), physicsClientId=client)
        targets.append(p.getLinkState(robot, ef, computeForwardKinematics=True, physicsClientId=client)[4])
    stdin = "\n".join(",".join(repr(v) for v in t) for t in targets) + "\n"
    result = run_cli("ik", "--batch", input=stdin, timeout=300)
    assert result.returncode == 0, result.stderr
    answers = [json.loads(line) for line in result.stdout.splitlines()]
    assert len(answers) == 1000
    failures = [a for a in answers if not a["ok"]]
    assert not failures, failures[:3]
    # Check the solutions with PyBullet, not with our own FK.
    worst = 0.0
    for target, answer in zip(targets, answers):
        assert all(abs(v) <= lim for v, lim in zip(answer["joints"], LIMITS))
        for j, v in zip(joints, answer["joints"]):
            p.resetJointState(robot, j, float(v), physicsClientId=client)
        reached = p.getLinkState(robot, ef, computeForwardKinematics=True, physicsClientId=client)[4]
        worst = max(worst, float(np.linalg.norm(np.subtract(reached, target))))
    print(f"IK over 1000 reachable targets: worst error {worst:.3e} m (checked by PyBullet)")
    assert worst < 1e-3


def test_ik_pointing_down_over_the_table(run_cli, bullet):
    """The cube spawn area of urdf/README.md, reached from above (checked by PyBullet)."""
    client, robot, joints, ef = bullet
    targets = [(x, y, z) for x in (0.43, 0.58, 0.73) for y in (-0.25, 0.0, 0.25) for z in (0.255, 0.45)]
    stdin = "\n".join(",".join(map(repr, t)) for t in targets) + "\n"
    result = run_cli("ik", "--batch", "--down", input=stdin)
    assert result.returncode == 0, result.stderr
    answers = [json.loads(line) for line in result.stdout.splitlines()]
    assert [a["ok"] for a in answers] == [True] * len(targets), answers
    for target, answer in zip(targets, answers):
        for j, v in zip(joints, answer["joints"]):
            p.resetJointState(robot, j, float(v), physicsClientId=client)
        state = p.getLinkState(robot, ef, computeForwardKinematics=True, physicsClientId=client)
        assert np.linalg.norm(np.subtract(state[4], target)) < 1e-3
        tool_z = np.array(p.getMatrixFromQuaternion(state[5])).reshape(3, 3)[:, 2]
        assert tool_z[2] < -0.9999, (target, tool_z)


def test_table_and_cube_urdfs(repo_root):
    client = p.connect(p.DIRECT)
    try:
        table = p.loadURDF(str(repo_root / "urdf" / "table.urdf"), useFixedBase=True, physicsClientId=client)
        top = p.getLinkState(table, 0, physicsClientId=client)[4]
        assert np.allclose(top, [0.58, 0.0, 0.18])
        shape = p.getCollisionShapeData(table, 0, physicsClientId=client)[0]
        assert np.allclose(shape[3], [0.4, 0.6, 0.04])  # box extents: top at 0.18 + 0.02 = 0.20 m
        cube = p.loadURDF(str(repo_root / "urdf" / "cube.urdf"), physicsClientId=client,
                          flags=p.URDF_USE_INERTIA_FROM_FILE)
        mass, _, inertia = p.getDynamicsInfo(cube, -1, physicsClientId=client)[:3]
        assert mass == pytest.approx(0.1)
        assert np.allclose(inertia, [0.1 * 0.05**2 / 6] * 3, rtol=1e-3)
        assert np.allclose(p.getCollisionShapeData(cube, -1, physicsClientId=client)[0][3], [0.05] * 3)
    finally:
        p.disconnect(client)


def test_collision_model_has_no_gaps_along_the_arm(bullet):
    """Every point of the kinematic skeleton (segments between successive link frames) lies
    inside the primitive collision shapes, so the cube cannot pass through the arm."""
    client, robot, joints, ef = bullet
    probe = p.createMultiBody(0, p.createCollisionShape(p.GEOM_SPHERE, radius=1e-3, physicsClientId=client),
                              physicsClientId=client)
    rng = np.random.default_rng(5)
    worst = -1.0
    try:
        for q in rng.uniform(-LIMITS, LIMITS, size=(10, 7)):
            for j, v in zip(joints, q):
                p.resetJointState(robot, j, float(v), physicsClientId=client)
            frames = [np.zeros(3)] + [
                np.array(p.getLinkState(robot, j, computeForwardKinematics=True, physicsClientId=client)[4])
                for j in range(p.getNumJoints(robot, physicsClientId=client))
            ]
            for a, b in zip(frames[:-1], frames[1:]):
                for t in np.linspace(0.0, 1.0, 9):
                    p.resetBasePositionAndOrientation(probe, (a + (b - a) * t).tolist(), [0, 0, 0, 1],
                                                      physicsClientId=client)
                    hits = p.getClosestPoints(probe, robot, 0.5, physicsClientId=client)
                    worst = max(worst, min(h[8] for h in hits))
    finally:
        p.removeBody(probe, physicsClientId=client)
    assert worst < 0.0, f"a skeleton point is {worst:.3f} m outside the collision model"


def test_unreachable_target_fails_clearly(run_cli):
    result = run_cli("ik", "--position", "3,0,0")
    assert result.returncode != 0
    assert "unreachable" in result.stderr and "(3.0000, 0.0000, 0.0000)" in result.stderr


def test_missing_urdf(run_cli, tmp_path):
    missing = tmp_path / "nope.urdf"
    result = run_cli("fk", "--joints", "0,0,0,0,0,0,0", "--urdf", missing)
    assert result.returncode != 0
    assert str(missing) in result.stderr and "cannot read URDF" in result.stderr


def test_malformed_urdf(run_cli, tmp_path):
    bad = tmp_path / "bad.urdf"
    bad.write_text("<robot name='x'><link name='a'>")
    result = run_cli("fk", "--joints", "0,0,0,0,0,0,0", "--urdf", bad)
    assert result.returncode != 0
    assert str(bad) in result.stderr and "malformed URDF" in result.stderr


def test_urdf_without_ef_frame(run_cli, tmp_path, urdf_path):
    broken = tmp_path / "no_ef.urdf"
    broken.write_text(urdf_path.read_text().replace('"ef"', '"tip"'))
    result = run_cli("fk", "--joints", "0,0,0,0,0,0,0", "--urdf", broken)
    assert result.returncode != 0
    assert 'link "ef" not found' in result.stderr


def test_wrong_joint_count(run_cli):
    result = run_cli("fk", "--joints", "0,0,0,0,0")
    assert result.returncode != 0
    assert "expected 7 joint values" in result.stderr and "got 5" in result.stderr


def test_out_of_limit_joint_is_named(run_cli):
    result = run_cli("fk", "--joints", "0,2.5,0,0,0,0,0")
    assert result.returncode != 0
    assert "iiwa_joint_2 = 2.5 rad is outside its limits [-2.094, 2.094]" in result.stderr


def test_non_numeric_joint(run_cli):
    result = run_cli("fk", "--joints", "0,zero,0,0,0,0,0")
    assert result.returncode != 0
    assert '"zero"' in result.stderr
