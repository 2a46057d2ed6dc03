"""Shared fixtures for the Python interop tests.

The tests drive our binaries as a user would and check them against independent
implementations installed from PyPI (cyclonedds, rosbags, mcap, pybullet).
`tests/run_all.sh` builds the binaries and runs pytest inside a private network
namespace, so DDS traffic never leaves the machine.
"""

import contextlib
import os
import pathlib
import signal
import subprocess
import tempfile

import pytest

REPO_ROOT = pathlib.Path(__file__).resolve().parents[2]


def _target_dir() -> pathlib.Path:
    return pathlib.Path(os.environ.get("CARGO_TARGET_DIR", REPO_ROOT / "target"))


@pytest.fixture(scope="session")
def repo_root() -> pathlib.Path:
    return REPO_ROOT


@pytest.fixture(scope="session")
def causal_arm_bin() -> pathlib.Path:
    """Path of the `causal-arm` CLI built by `cargo build` (override with CAUSAL_ARM_BIN)."""
    path = pathlib.Path(os.environ.get("CAUSAL_ARM_BIN", _target_dir() / "debug" / "causal-arm"))
    if not path.exists():
        pytest.fail(f"{path} does not exist: run `cargo build --workspace --bins` first")
    return path


@pytest.fixture(scope="session")
def run_cli(causal_arm_bin):
    """Run `causal-arm ARGS…` and return the CompletedProcess (text mode, never raises).

    A run that outlives `timeout` is killed and returned with returncode -9 and what it
    printed so far, ending in a line saying so, so the failing assertion shows where the
    command stood instead of a bare TimeoutExpired."""

    def run(*args, input=None, timeout=120, env=None):
        full_env = dict(os.environ)
        if env:
            full_env.update(env)
        command = [str(causal_arm_bin), *map(str, args)]
        try:
            return subprocess.run(command, input=input, capture_output=True, text=True, timeout=timeout,
                                  env=full_env)
        except subprocess.TimeoutExpired as e:
            text = lambda b: b.decode(errors="replace") if isinstance(b, bytes) else (b or "")
            stderr = text(e.stderr) + f"\n[test harness: killed after {timeout} s: {' '.join(command)}]"
            return subprocess.CompletedProcess(command, -9, text(e.stdout), stderr)

    return run


def bag_and_forward_model(run_cli, d, generate_args, train_args):
    """Generates `d/bag` (`causal-arm generate GENERATE_ARGS`) and trains a forward model on
    it into `d/models` (cache `d/cache`); fails the test with the tool's stderr otherwise."""
    r = run_cli("generate", *generate_args, "--out", d / "bag")
    assert r.returncode == 0, r.stderr
    r = run_cli("train", "--bag", d / "bag", "--model", "fm", *train_args, "--out", d / "models",
                "--cache", d / "cache", timeout=300)
    assert r.returncode == 0, r.stderr


def custom_data(bag: pathlib.Path) -> dict:
    """The run settings a bag's metadata.yaml records (rosbag2 `custom_data`)."""
    import yaml

    info = yaml.safe_load((pathlib.Path(bag) / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    return info["custom_data"]


def network_interfaces() -> list:
    """Interfaces of this process's network namespace (/proc/net/dev is per namespace;
    /sys/class/net is not, unless sysfs is remounted)."""
    with open("/proc/net/dev") as f:
        return [line.split(":")[0].strip() for line in f.readlines()[2:]]


def in_private_netns() -> bool:
    """True when every network interface is loopback (see tests/netns-run)."""
    return network_interfaces() == ["lo"]


def require_private_netns():
    """Refuse to start a DDS participant unless we run inside a loopback-only namespace."""
    if not in_private_netns():
        pytest.fail("DDS tests must run inside tests/netns-run (found interfaces: "
                    + ", ".join(network_interfaces()) + ")")


@pytest.fixture
def private_netns():
    require_private_netns()


@pytest.fixture(scope="module")
def private_netns_module():
    """`private_netns` for module-scoped fixtures (a node shared by a module's tests)."""
    require_private_netns()


@contextlib.contextmanager
def node_process(binary, ros_args, env):
    """Runs a node binary (`BINARY --ros-args ROS_ARGS…`) for the duration of the block, then
    stops it with SIGINT as a user would (killed after 10 s).

    Its stdout and stderr go to one temporary file, never to a pipe: a pipe nobody reads
    fills at 64 KiB of log lines and then blocks the node's logging, so a long-lived node
    that warned a lot would stop answering. `proc.log()` returns what it printed so far."""
    with tempfile.NamedTemporaryFile("w+", prefix=f"{pathlib.Path(binary).name}-", suffix=".log") as log:
        proc = subprocess.Popen([str(binary), "--ros-args", *map(str, ros_args)], env=env,
                                stdout=log, stderr=subprocess.STDOUT, text=True)
        proc.log = lambda: pathlib.Path(log.name).read_text(errors="replace")
        try:
            yield proc
        finally:
            proc.send_signal(signal.SIGINT)
            try:
                proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
