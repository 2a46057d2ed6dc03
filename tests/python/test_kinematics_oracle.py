"""Our kinematics against PyBullet on the same URDF file, and the CLI's error messages.

PyBullet is an independent URDF loader and FK implementation, so agreement to 1e-6 on
1,000 random in-limit configurations shows the arm model (origins, rpy convention, axes,
fixed tool frames) is read correctly.
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


def test_fk_matches_pybullet_on_1000_configurations(run_cli, bullet, urdf_path):
    client, robot, joints, ef = bullet
    rng = np.random.default_rng(2024)
    configs = rng.uniform(-LIMITS, LIMITS, size=(1000, 7))
    stdin = "\n".join(",".join(repr(float(v)) for v in q) for q in configs) + "\n"
    result = run_cli("fk", "--batch", "--urdf", urdf_path, input=stdin)
    assert result.returncode == 0, result.stderr
    ours = [json.loads(line) for line in result.stdout.splitlines()]
    assert len(ours) == 1000
    max_pos, max_rot = 0.0, 0.0
    for q, mine in zip(configs, ours):
        for j, v in zip(joints, q):
            p.resetJointState(robot, j, float(v), physicsClientId=client)
        state = p.getLinkState(robot, ef, computeForwardKinematics=True, physicsClientId=client)
        pos, orn = np.array(state[4]), np.array(state[5])
        max_pos = max(max_pos, float(np.max(np.abs(pos - mine["position"]))))
        max_rot = max(max_rot, _angle_between(orn, np.array(mine["orientation_xyzw"])))
    print(f"FK vs PyBullet over 1000 configs: max |dp| = {max_pos:.3e} m, max angle = {max_rot:.3e} rad")
    assert max_pos <= 1e-6
    assert max_rot <= 1e-6


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
