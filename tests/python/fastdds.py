"""The Fast DDS peer (tests/fastdds/fastdds_peer.cpp): built once per test session from
Debian's libfastrtps-dev, then run as a subprocess that speaks as rmw_fastrtps does.

Samples cross its command line as hex of the serialized bytes; this module turns them into
the CycloneDDS Python IDL classes of ros_idl, an independent CDR implementation.

rmw_fastrtps's service payloads carry no header (the request id travels as the related
sample identity), while ros_idl's request and reply classes start with rmw_cyclonedds's
16-octet header (client GUID, sequence number). That header is 8-aligned and first, so the
Fast DDS payload is the CycloneDDS one without octets 4..20, and adding 16 zero octets there
decodes a Fast DDS payload with the same class.
"""

import hashlib
import os
import queue
import pathlib
import shutil
import subprocess
import threading
import time
import warnings

import pytest

REPO_ROOT = pathlib.Path(__file__).resolve().parents[2]
SOURCE = REPO_ROOT / "tests" / "fastdds" / "fastdds_peer.cpp"
HEADER = slice(4, 20)

# Debian 12's Fast DDS 2.9.1 is built with assertions and aborts in its statistics module
# ("OutputTrafficManager.hpp:87 … Assertion `it != collection_.end()' failed") when a writer
# sends to a remote locator it created no sender resource for, a race with discovery of a
# new participant: about 1 peer run in 15 here. Fixed upstream in Fast DDS 3.2.0, 3.1.3, 2.14.5
# and 2.10.7 (eProsima/Fast-DDS#5704, "Fix assertion on OutputTrafficManager"). Only a peer that died
# with exactly this signature is run again; every other failure fails the test.
UPSTREAM_ABORT = "OutputTrafficManager.hpp"
ATTEMPTS = 3


class PeerAborted(Exception):
    """The Fast DDS peer died of the upstream statistics assertion, not of anything we sent."""


def check_upstream_abort(stderr: str):
    """Raises PeerAborted when the peer's stderr shows the upstream Fast DDS 2.9 abort."""
    if UPSTREAM_ABORT in stderr and "Assertion" in stderr:
        raise PeerAborted(stderr[-500:])


def retry_upstream_abort(scenario):
    """Runs `scenario()` (which starts its own peer) up to ATTEMPTS times while the peer dies
    of the upstream Fast DDS 2.9 abort; says so as a warning each time; returns its result."""
    for attempt in range(1, ATTEMPTS + 1):
        try:
            return scenario()
        except PeerAborted as e:
            warnings.warn(f"Fast DDS peer hit the upstream 2.9.1 statistics abort (attempt {attempt}): {e}")
            if attempt == ATTEMPTS:
                raise


def build() -> pathlib.Path:
    """Compiles the peer into the target dir (cached by the source's hash); fails the test
    with the compiler's message when libfastrtps-dev or a C++ compiler is missing."""
    target = pathlib.Path(os.environ.get("CARGO_TARGET_DIR", REPO_ROOT / "target")) / "fastdds"
    digest = hashlib.sha256(SOURCE.read_bytes()).hexdigest()[:16]
    binary = target / f"fastdds_peer-{digest}"
    if binary.exists():
        return binary
    if shutil.which("g++") is None:
        pytest.fail("g++ is needed to build the Fast DDS peer (apt install build-essential)")
    target.mkdir(parents=True, exist_ok=True)
    r = subprocess.run(["g++", "-std=c++17", "-O1", "-Wall", "-Wextra", "-o", str(binary), str(SOURCE),
                        "-lfastrtps", "-lfastcdr"], capture_output=True, text=True)
    if r.returncode != 0:
        pytest.fail("building the Fast DDS peer failed (is libfastrtps-dev installed?):\n" + r.stderr[-3000:])
    return binary


def enhanced_payload(request) -> bytes:
    """The rmw_fastrtps payload of a ros_idl request or reply (its rmw_cyclonedds header cut)."""
    data = request.serialize()
    return data[:HEADER.start] + data[HEADER.stop:]


def from_enhanced(cls, payload: bytes):
    """Decodes an rmw_fastrtps service payload with a ros_idl class that has the header."""
    return cls.deserialize(payload[:HEADER.start] + bytes(HEADER.stop - HEADER.start) + payload[HEADER.start:])


def env(domain: int) -> dict:
    return dict(os.environ, ROS_DOMAIN_ID=str(domain))


def call(peer, domain, service, request_cls, reply_cls, requests, timeout=60.0, server=None):
    """Sends all requests at once from a Fast DDS client, as rmw_fastrtps does; returns the
    decoded replies in request order (the peer matched each by related sample identity).
    With `server` (a `node_process`), a failure shows the end of that node's log too."""
    lines = "".join(enhanced_payload(r).hex() + "\n" for r in requests)

    def run():
        r = subprocess.run([str(peer), "call", service, request_cls.__idl_typename__, reply_cls.__idl_typename__,
                            str(timeout)], input=lines, capture_output=True, text=True, env=env(domain),
                           timeout=timeout + 30)
        check_upstream_abort(r.stderr)
        return r

    r = retry_upstream_abort(run)
    server_log = f"\nserver log:\n{server.log()[-3000:]}" if server is not None else ""
    assert r.returncode == 0, f"fastdds_peer call {service}: {r.stderr[-2000:]}{server_log}"
    replies = {}
    for line in r.stdout.splitlines():
        index, payload = line.split(" ")
        replies[int(index)] = from_enhanced(reply_cls, bytes.fromhex(payload))
    assert sorted(replies) == list(range(len(requests))), r.stdout[:200]
    return [replies[i] for i in range(len(requests))]


def discover(peer, domain, required, timeout=60.0, linger=1.0) -> dict:
    """Runs the peer's discovery listener until every (kind, topic) in `required` has been
    announced (and `linger` seconds more, for the rest), or `timeout` seconds passed; returns {(kind, topic): (type, user_data)} for
    every endpoint seen. Waiting for the set, not a fixed window, keeps a loaded machine's
    slow discovery from passing for a missing announcement."""
    proc = subprocess.Popen([str(peer), "discover", str(timeout)], env=env(domain),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    endpoints, pending = {}, set(required)
    lines = queue.Queue()  # a thread reads the pipe: select() cannot see lines already buffered

    def read_lines():
        for line in proc.stdout:
            lines.put(line)
        lines.put(None)

    threading.Thread(target=read_lines, daemon=True).start()
    deadline = time.monotonic() + timeout
    try:
        while time.monotonic() < deadline:
            try:
                line = lines.get(timeout=max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                break
            if line is None:
                break
            kind, topic, type_name, user_data = (line.rstrip("\n").split(" ") + [""])[:4]
            endpoints[(kind, topic)] = (type_name, bytes.fromhex(user_data))
            if (kind, topic) in pending:
                pending.remove((kind, topic))
                if not pending:  # all there: collect the rest for `linger` seconds
                    deadline = min(deadline, time.monotonic() + linger)
    finally:
        proc.kill()
        proc.wait()
    err = proc.stderr.read()
    assert not pending, f"not discovered within {timeout} s: {sorted(pending)}; seen: {sorted(endpoints)}; {err[-1000:]}"
    return endpoints
