"""The tests' handle on a real rclpy node (tests/ros2/peer.py) running on rmw_fastrtps_cpp
under a ROS 2 distribution's wheels, built by tests/ros2/setup.sh into target/ros/DISTRO."""

import json
import pathlib
import subprocess

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
DISTROS = ["jazzy", "kilted"]


def distro_env_script(distro: str) -> pathlib.Path:
    """target/ros/DISTRO/env.sh, or a test failure saying how to make it."""
    script = ROOT / "target" / "ros" / distro / "env.sh"
    if not script.exists():
        pytest.fail(f"{script} does not exist: run `bash tests/ros2/setup.sh {distro}` "
                    "(tests/run_all.sh does)")
    return script


class RclpyPeer:
    """One rclpy node in its own process; every method is a request answered in JSON.

    `peer.take("/joint_states", count=10, timeout=5)` calls Peer.take in tests/ros2/peer.py."""

    def __init__(self, distro: str, name: str, env: dict):
        script = distro_env_script(distro)
        command = f'source "{script}" && exec python "{ROOT}/tests/ros2/peer.py" {name}'
        self.proc = subprocess.Popen(["bash", "-c", command], env=env, stdin=subprocess.PIPE,
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        first = self.proc.stdout.readline()
        if not first:
            raise RuntimeError(f"rclpy peer ({distro}) did not start: {self.proc.stderr.read()[-3000:]}")
        self.info = json.loads(first)["ok"]

    def request(self, op: str, **args):
        self.proc.stdin.write(json.dumps({"op": op, **args}) + "\n")
        self.proc.stdin.flush()
        line = self.proc.stdout.readline()
        if not line:
            raise RuntimeError(f"rclpy peer died during {op}: {self.proc.stderr.read()[-3000:]}")
        answer = json.loads(line)
        if "error" in answer:
            raise RuntimeError(f"rclpy peer {op}: {answer['error']}")
        return answer["ok"]

    def __getattr__(self, op):
        return lambda **args: self.request(op, **args)

    def close(self):
        try:
            self.proc.stdin.close()
            self.proc.wait(timeout=10)
        except (OSError, subprocess.TimeoutExpired):
            self.proc.kill()
            self.proc.wait()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
