"""SROS2 security: a keystore from `causal-arm security`, nodes under `ROS_SECURITY_*`.

- A secured publisher and subscriber exchange joint states; a CycloneDDS participant without
  credentials receives none of them (the unsecured control shows the same subscriber does).
- A loopback capture of the secured pair holds no plaintext: no joint name, no topic name, no
  type name (the unsecured control capture holds them, so the capture does see traffic).
- The secured graph (four participants, one enclave given to `launch --enclave`) records a
  complete bag, equal to `generate` of the same seed.
- The secured trainer node answers a secured `service call`; the same call without
  credentials finds no server.
- Under `ROS_SECURITY_STRATEGY=Enforce` a node without an enclave cannot start;
  `Permissive` runs it unsecured and says so.
Run inside `tests/netns-run`, as the test command does (raw capture needs the namespace's
CAP_NET_RAW, which the user namespace gives).
"""

import json
import os
import signal
import socket
import subprocess
import threading
import time

import pytest
from cyclonedds.domain import DomainParticipant
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic

from ros_idl import JointState
from test_datagen import assert_same_bag

DOMAIN = 41
ENCLAVE = "/causal_arm"
STEPS = 1000


@pytest.fixture(scope="module")
def keystore(run_cli, tmp_path_factory):
    root = tmp_path_factory.mktemp("sros2") / "keystore"
    env = {"ROS_DOMAIN_ID": str(DOMAIN)}
    r = run_cli("security", "create-keystore", root, env=env)
    assert r.returncode == 0, r.stderr
    r = run_cli("security", "create-enclave", root, ENCLAVE, env=env)
    assert r.returncode == 0, r.stderr
    r = run_cli("security", "list-enclaves", root)
    assert r.stdout.split() == [ENCLAVE], r.stdout
    return root


def _secured_env(keystore, strategy="Enforce", enclave=ENCLAVE):
    env = {
        "ROS_DOMAIN_ID": str(DOMAIN),
        "RUST_LOG": "warn",
        "ROS_SECURITY_ENABLE": "true",
        "ROS_SECURITY_STRATEGY": strategy,
        "ROS_SECURITY_KEYSTORE": str(keystore),
    }
    if enclave:
        env["ROS_SECURITY_ENCLAVE_OVERRIDE"] = enclave
    return env


class LoopbackCapture:
    """Every frame on `lo` while active (AF_PACKET, as tcpdump would see it)."""

    def __init__(self):
        self.sock = socket.socket(socket.AF_PACKET, socket.SOCK_RAW, socket.ntohs(0x0003))
        self.sock.bind(("lo", 0))
        self.sock.settimeout(0.2)
        self.frames = []
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)

    def _run(self):
        while not self.stop.is_set():
            try:
                self.frames.append(self.sock.recv(65535))
            except socket.timeout:
                pass

    def __enter__(self):
        self.thread.start()
        return self

    def __exit__(self, *exc):
        self.stop.set()
        self.thread.join()
        self.sock.close()

    def ours(self):
        """Frames of RTPS messages from rustdds (vendor 01.12), not from the eavesdropper."""
        for frame in self.frames:
            at = frame.find(b"RTPS")
            if at >= 0 and frame[at + 6:at + 8] == b"\x01\x12":
                yield frame

    def contains(self, needle: bytes) -> int:
        return sum(needle in f for f in self.ours())


class Eavesdropper:
    """A CycloneDDS participant without credentials, subscribed to /joint_states."""

    def __enter__(self):
        self.participant = DomainParticipant(DOMAIN)
        self.reader = DataReader(self.participant, Topic(self.participant, "rt/joint_states", JointState))
        self.got = 0
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()
        return self

    def _run(self):
        while not self.stop.is_set():
            self.got += sum(isinstance(s, JointState) for s in self.reader.take(N=100))
            time.sleep(0.01)

    def __exit__(self, *exc):
        self.stop.set()
        self.thread.join()


JOINT_STATE = '{"name": ["iiwa_joint_1", "iiwa_joint_2"], "position": [0.25, -0.5]}'


def _talk(causal_arm_bin, env, count=40):
    """A `topic echo` and a `topic pub` of /joint_states under `env`; returns what echo got."""
    full = {**os.environ, **env}
    echo = subprocess.Popen(
        [str(causal_arm_bin), "topic", "echo", "/joint_states", "--type", "sensor_msgs/msg/JointState",
         "--count", str(count)],
        env=full, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        pub = subprocess.run(
            [str(causal_arm_bin), "topic", "pub", "/joint_states", "--type", "sensor_msgs/msg/JointState",
             "--json", JOINT_STATE, "--count", str(count), "--rate", "50", "--wait-subscribers", "1",
             "--timeout", "60", "--settle", "1.5"],
            env=full, capture_output=True, text=True, timeout=120)
        assert pub.returncode == 0, pub.stderr[-3000:]
        out, err = echo.communicate(timeout=60)
    finally:
        if echo.poll() is None:
            echo.kill()
            echo.wait()
    assert echo.returncode == 0, err[-3000:]
    return out.splitlines()


def test_an_unauthenticated_peer_gets_nothing_and_loopback_carries_no_plaintext(
        causal_arm_bin, keystore, private_netns):
    with LoopbackCapture() as capture, Eavesdropper() as spy:
        got = _talk(causal_arm_bin, _secured_env(keystore))
        time.sleep(0.5)
    assert len(got) == 40 and all("iiwa_joint_1" in line for line in got), got[:3]
    assert sum(1 for _ in capture.ours()) > 50, "the capture saw no traffic of our nodes"
    assert spy.got == 0, f"an unauthenticated CycloneDDS reader got {spy.got} joint states"
    for plaintext in (b"iiwa_joint_1", b"joint_states", b"JointState"):
        assert capture.contains(plaintext) == 0, f"{plaintext!r} crossed loopback in plaintext"


def test_control_the_same_eavesdropper_and_capture_see_an_unsecured_pair(causal_arm_bin, private_netns):
    with LoopbackCapture() as capture, Eavesdropper() as spy:
        _talk(causal_arm_bin, {"ROS_DOMAIN_ID": str(DOMAIN), "RUST_LOG": "warn"})
        time.sleep(0.5)
    assert spy.got > 0
    assert capture.contains(b"iiwa_joint_1") > 0 and capture.contains(b"joint_states") > 0


def _thread_stacks(pid):
    """Every thread's stack of a stalled process, so a hang seen once in CI names its locks."""
    try:
        r = subprocess.run(["gdb", "-p", str(pid), "-batch", "-ex", "thread apply all bt 40"],
                           capture_output=True, text=True, timeout=60)
    except (OSError, subprocess.TimeoutExpired) as e:
        return f"(no stacks: {e})"
    return "\n".join(line for line in r.stdout.splitlines() if line.startswith(("Thread", "#")))


def _launch_or_explain_the_stall(causal_arm_bin, args, env, timeout):
    """Runs `causal-arm launch ARGS`; if it has not ended after `timeout` s, interrupts it as
    a user would (so it stops its nodes and says how far it got) and fails with its output."""
    proc = subprocess.Popen([str(causal_arm_bin), "launch", *map(str, args)], env={**os.environ, **env},
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        out, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        stacks = _thread_stacks(proc.pid)
        proc.send_signal(signal.SIGINT)
        try:
            out, err = proc.communicate(timeout=60)
        except subprocess.TimeoutExpired:
            proc.kill()
            out, err = proc.communicate()
        useful = [line for line in err.splitlines() if "Submessage decoding failed" not in line]
        pytest.fail(f"launch did not end within {timeout} s; after SIGINT: stdout {out!r}; "
                    "stderr (decode errors left out):\n" + "\n".join(useful[-60:])
                    + "\nthreads at the stall:\n" + stacks)
    return subprocess.CompletedProcess(proc.args, proc.returncode, out, err)


@pytest.mark.parametrize("composed", [False, True], ids=["processes", "composed"])
def test_secured_graph_records_a_complete_bag_equal_to_generate(run_cli, causal_arm_bin, keystore, tmp_path,
                                                               private_netns, composed):
    """Also with the nodes composed in one process: each still joins with the enclave."""
    env = _secured_env(keystore, enclave=None)
    r = _launch_or_explain_the_stall(causal_arm_bin, ["exp1", "--steps", STEPS, "--seed", "4", "--out",
                                                      tmp_path / "secured"] + ["--composed"] * composed
                                     + ["--ros-args", "--enclave", ENCLAVE],
                                     env, timeout=120)
    assert r.returncode == 0, r.stderr[-3000:]
    assert f"{STEPS} of {STEPS} steps" in r.stdout, r.stdout
    assert "WITHOUT security" not in r.stderr
    local = tmp_path / "local"
    g = run_cli("generate", "exp1", "--steps", str(STEPS), "--seed", "4", "--out", local)
    assert g.returncode == 0, g.stderr
    assert_same_bag(tmp_path / "secured", local, "differs from the in-process run")


def test_enforce_refuses_a_node_without_an_enclave_and_permissive_warns(run_cli, keystore, private_netns):
    no_enclave = _secured_env(keystore, enclave=None)
    args = ("topic", "pub", "/chatter", "--type", "std_msgs/msg/String", "--json", '{"data": "x"}',
            "--linger", "0")
    start = time.monotonic()
    r = run_cli(*args, env=no_enclave, timeout=30)
    assert r.returncode != 0
    assert "ROS_SECURITY_STRATEGY=Enforce" in r.stderr and "enclave \"/\"" in r.stderr, r.stderr
    assert time.monotonic() - start < 10
    r = run_cli(*args, "--ros-args", "--enclave", "/absent", env=no_enclave, timeout=30)
    assert r.returncode != 0 and "enclave \"/absent\" not found" in r.stderr, r.stderr

    permissive = _secured_env(keystore, strategy="Permissive", enclave=None)
    r = run_cli(*args, env=permissive, timeout=30)
    assert r.returncode == 0, r.stderr
    assert "running WITHOUT security" in r.stderr, r.stderr

    typo = {**no_enclave, "ROS_SECURITY_ENABLE": "True"}
    r = run_cli(*args, env=typo, timeout=30)
    assert r.returncode != 0 and "ROS_SECURITY_ENABLE=\"True\"" in r.stderr, r.stderr


def test_secured_trainer_service_answers_a_secured_client_only(run_cli, causal_arm_bin, keystore, tmp_path,
                                                              private_netns):
    from conftest import bag_and_forward_model, node_process

    bag_and_forward_model(run_cli, tmp_path, ["exp1", "--steps", "600", "--seed", "2"],
                          ["--epochs", "2", "--folds", "2", "--fm-hidden", "16"])
    env = {**os.environ, **_secured_env(keystore, enclave=None)}
    request = '{"state":[0,0.5,0,-1.2,0,0.8,0,0.55,0,0.45],"action":[0.05,0,0,0,0,0,0],"rows":1}'
    call = ("service", "call", "/trainer/predict_next_state", "--type", "causal_arm_msgs/srv/PredictNextState",
            "--json", request)
    trainer = causal_arm_bin.parent / "causal_arm_trainer"
    with node_process(trainer, ["--enclave", ENCLAVE, "-p", f"model_dir:={tmp_path / 'models'}"], env):
        r = run_cli(*call, "--ros-args", "--enclave", ENCLAVE, env=_secured_env(keystore, enclave=None),
                    timeout=90)
        assert r.returncode == 0, r.stderr[-3000:]
        reply = json.loads(r.stdout)
        assert reply["success"] and len(reply["next_state"]) == 10, reply
        # The same call without credentials finds no server.
        r = run_cli(*call, "--timeout", "5", env={"ROS_DOMAIN_ID": str(DOMAIN), "RUST_LOG": "warn"}, timeout=60)
        assert r.returncode != 0, r.stdout
