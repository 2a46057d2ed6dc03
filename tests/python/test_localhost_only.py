"""`ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST` keeps the whole graph on loopback.

The test's private namespace gets a second interface: one end of a veth pair whose other end
sits in a namespace the test creates itself, so nothing can leave the machine either way.
A full `launch` with LOCALHOST must send zero packets through it. The control run with SUBNET
(the ROS 2 default) shows the counter sees DDS traffic when there is some.
Run inside `tests/netns-run`, as the test command does.
"""

import os
import pathlib
import subprocess
import time

import pytest

OUT_IF, PEER_IF = "ca_out0", "ca_peer0"


def _ip(*args, netns_pid=None):
    prefix = ["nsenter", f"--net=/proc/{netns_pid}/ns/net"] if netns_pid else []
    subprocess.run([*prefix, "ip", *args], check=True, capture_output=True, text=True)


@pytest.fixture
def second_interface(private_netns):
    """A veth `ca_out0` (10.213.0.1/24, up, multicast) into a peer namespace of our own."""
    peer = subprocess.Popen(["unshare", "-n", "sleep", "600"])
    try:
        # The peer namespace exists once unshare has exec'd sleep.
        for _ in range(100):
            if os.readlink(f"/proc/{peer.pid}/ns/net") != os.readlink("/proc/self/ns/net"):
                break
            time.sleep(0.05)
        else:
            raise AssertionError("the peer namespace did not appear")
        _ip("link", "add", OUT_IF, "type", "veth", "peer", "name", PEER_IF, "netns", str(peer.pid))
        # No IPv6 on it: the kernel's own neighbour discovery and MLD packets would count.
        subprocess.run(["sysctl", "-qw", f"net.ipv6.conf.{OUT_IF}.disable_ipv6=1"], check=True)
        _ip("addr", "add", "10.213.0.1/24", "dev", OUT_IF)
        _ip("link", "set", OUT_IF, "up", "multicast", "on")
        _ip("addr", "add", "10.213.0.2/24", "dev", PEER_IF, netns_pid=peer.pid)
        _ip("link", "set", PEER_IF, "up", netns_pid=peer.pid)
        yield OUT_IF
    finally:
        subprocess.run(["ip", "link", "del", OUT_IF], capture_output=True)
        peer.kill()
        peer.wait()


def _tx_packets(interface):
    """Packets sent through `interface`, from this namespace's /proc/net/dev (sysfs may show
    the host's namespace)."""
    for line in pathlib.Path("/proc/self/net/dev").read_text().splitlines()[2:]:
        name, counters = line.split(":", 1)
        if name.strip() == interface:
            return int(counters.split()[9])
    raise AssertionError(f"{interface} not found in /proc/self/net/dev")


def _launch(run_cli, tmp_path, discovery_range):
    env = {"ROS_DOMAIN_ID": "23", "RUST_LOG": "warn", "ROS_AUTOMATIC_DISCOVERY_RANGE": discovery_range}
    out = tmp_path / discovery_range.lower()
    r = run_cli("launch", "exp1", "--steps", "2000", "--seed", "4", "--out", out, env=env, timeout=300)
    assert r.returncode == 0, r.stderr[-3000:]
    assert "2000 of 2000 steps" in r.stdout, r.stdout


def test_a_localhost_graph_sends_nothing_through_another_interface(run_cli, tmp_path, second_interface):
    before = _tx_packets(second_interface)
    _launch(run_cli, tmp_path, "LOCALHOST")
    assert _tx_packets(second_interface) == before, "packets left through a non-loopback interface"


def test_control_a_subnet_graph_does_use_the_other_interface(run_cli, tmp_path, second_interface):
    before = _tx_packets(second_interface)
    _launch(run_cli, tmp_path, "SUBNET")
    assert _tx_packets(second_interface) > before
