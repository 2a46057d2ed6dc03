"""A real rclpy node, driven line by line over stdin/stdout by the interop tests.

Runs under the ROS 2 wheels' Python (tests/ros2/setup.sh makes the venv and the colcon-built
interfaces); the tests, in their own venv, talk to it through `tests/python/rclpy_peer.py`.
Each request is one JSON object per line ({"op": ..., ...}); each answer one JSON line
({"ok": value} or {"error": text}). The node spins in a background thread, so subscriptions
keep receiving between requests.
"""

import importlib
import json
import sys
import threading
import time

import rclpy
from rclpy.executors import MultiThreadedExecutor
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy


def interface(type_name: str):
    """`pkg/msg/Name` or `pkg/srv/Name` → the generated class."""
    pkg, kind, name = type_name.split("/")
    return getattr(importlib.import_module(f"{pkg}.{kind}"), name)


def to_dict(value):
    """A message (or field value) as plain JSON data."""
    if hasattr(value, "get_fields_and_field_types"):
        return {f: to_dict(getattr(value, f)) for f in value.get_fields_and_field_types()}
    if isinstance(value, (list, tuple)) or type(value).__name__ in ("ndarray", "array"):
        return [to_dict(v) for v in value]
    if isinstance(value, bytes):
        return list(value)
    if hasattr(value, "item"):
        return value.item()
    return value


def from_dict(cls, data: dict):
    """A message of `cls` with the fields `data` gives (nested messages from nested dicts)."""
    msg = cls()
    for field, value in data.items():
        current = getattr(msg, field)
        if isinstance(value, dict):
            value = from_dict(type(current), value)
        elif isinstance(value, list) and value and isinstance(value[0], dict):
            element = _element_class(cls, field)
            value = [from_dict(element, v) for v in value]
        setattr(msg, field, value)
    return msg


def _element_class(cls, field):
    """The message class of a sequence field's elements (`sequence<pkg/Name>` in rosidl)."""
    spec = cls.get_fields_and_field_types()[field]
    inner = spec[spec.index("<") + 1:spec.rindex(">")].split(",")[0]
    pkg, name = inner.split("/")
    return getattr(importlib.import_module(f"{pkg}.msg"), name)


def qos_of(spec: dict) -> QoSProfile:
    return QoSProfile(
        depth=spec.get("depth", 10),
        reliability=ReliabilityPolicy.BEST_EFFORT if spec.get("best_effort") else ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if spec.get("transient_local") else DurabilityPolicy.VOLATILE,
    )


def endpoint_to_dict(info):
    type_hash = getattr(info, "topic_type_hash", None)
    return {
        "node_name": info.node_name,
        "node_namespace": info.node_namespace,
        "topic_type": info.topic_type,
        "type_hash": str(type_hash) if type_hash is not None else None,
        "reliability": info.qos_profile.reliability.name,
        "durability": info.qos_profile.durability.name,
    }


class Peer:
    """The requests the tests can make of a live rclpy node."""

    def __init__(self, node):
        self.node = node
        self.inbox = {}  # topic → [(receive time, message dict)]
        self.lock = threading.Lock()
        self.publishers = {}

    def subscribe(self, topic, type, qos=None):
        self.inbox.setdefault(topic, [])

        def received(msg, topic=topic):
            with self.lock:
                self.inbox[topic].append((time.monotonic(), to_dict(msg)))

        self.node.create_subscription(interface(type), topic, received, qos_of(qos or {}))
        return time.monotonic()

    def take(self, topic, count=0, timeout=0.0):
        """What `topic` received so far, waiting up to `timeout` s for at least `count`."""
        deadline = time.monotonic() + timeout
        while len(self.inbox[topic]) < count and time.monotonic() < deadline:
            time.sleep(0.01)
        with self.lock:
            got, self.inbox[topic] = self.inbox[topic], []
        return [{"t": t, "msg": m} for t, m in got]

    def publish(self, topic, type, messages, qos=None, period=0.0, wait_subscribers=0, timeout=10.0):
        key = (topic, type)
        if key not in self.publishers:
            self.publishers[key] = self.node.create_publisher(interface(type), topic, qos_of(qos or {}))
        publisher = self.publishers[key]
        deadline = time.monotonic() + timeout
        while publisher.get_subscription_count() < wait_subscribers:
            if time.monotonic() > deadline:
                raise TimeoutError(f"{topic}: {publisher.get_subscription_count()} of {wait_subscribers} subscribers")
            time.sleep(0.01)
        for data in messages:
            publisher.publish(from_dict(interface(type), data))
            time.sleep(period)
        return len(messages)

    def call(self, service, type, requests, timeout=30.0):
        """Sends every request at once (futures), returns the replies in order."""
        cls = interface(type)
        client = self.node.create_client(cls, service)
        try:
            if not client.wait_for_service(timeout_sec=timeout):
                raise TimeoutError(f"no server for {service} within {timeout} s")
            futures = [client.call_async(from_dict(cls.Request, r)) for r in requests]
            deadline = time.monotonic() + timeout
            while not all(f.done() for f in futures):
                if time.monotonic() > deadline:
                    done = sum(f.done() for f in futures)
                    raise TimeoutError(f"{service}: {done} of {len(futures)} replies within {timeout} s")
                time.sleep(0.005)
            return [to_dict(f.result()) for f in futures]
        finally:
            self.node.destroy_client(client)

    def serve(self, service, type, reply):
        """Serves `service` with `reply` to every request; `served` returns the requests."""
        cls = interface(type)
        self.inbox.setdefault(service, [])

        def answer(request, response, service=service):
            with self.lock:
                self.inbox[service].append((time.monotonic(), to_dict(request)))
            return from_dict(cls.Response, reply)

        self.node.create_service(cls, service, answer)
        return True

    def served(self, service, count=0, timeout=0.0):
        """The requests `service` answered so far (as `take` gives a topic's samples)."""
        return self.take(topic=service, count=count, timeout=timeout)

    def set_own_parameters(self, values):
        """Sets this node's parameters (e.g. `{"use_sim_time": true}`), as `ros2 param set` would."""
        from rclpy.parameter import Parameter

        results = self.node.set_parameters([Parameter(k, value=v) for k, v in values.items()])
        return [r.successful for r in results]

    def clock_now(self):
        """This node's clock in ns: simulated time from /clock once `use_sim_time` is true."""
        return self.node.get_clock().now().nanoseconds

    def graph(self):
        """The graph as `ros2 node list` / `ros2 node info` / `ros2 topic info -v` see it."""
        n = self.node
        nodes = {}
        for name, namespace in n.get_node_names_and_namespaces():
            full = (namespace.rstrip("/") + "/" + name)
            try:
                nodes[full] = {
                    "publishers": dict(n.get_publisher_names_and_types_by_node(name, namespace)),
                    "subscriptions": dict(n.get_subscriber_names_and_types_by_node(name, namespace)),
                    "services": dict(n.get_service_names_and_types_by_node(name, namespace)),
                }
            except Exception as e:  # a node that left between the two calls
                nodes[full] = {"error": str(e)}
        return {"nodes": nodes, "topics": dict(n.get_topic_names_and_types())}

    def endpoints(self, topic, no_mangle=False):
        """`ros2 topic info -v`; with `no_mangle`, a DDS topic name as is (`rq/...Request`)."""
        n = self.node
        return {
            "publishers": [endpoint_to_dict(i) for i in n.get_publishers_info_by_topic(topic, no_mangle)],
            "subscriptions": [endpoint_to_dict(i) for i in n.get_subscriptions_info_by_topic(topic, no_mangle)],
        }

    def endpoints_of(self, topics, no_mangle=False):
        """`endpoints` of several topics in one request."""
        return {topic: self.endpoints(topic, no_mangle) for topic in topics}

    def own_type_hash(self, type):
        """The type hash this rclpy gives `type`: from its own publisher's endpoint."""
        topic = "/rclpy_peer_type_probe_" + type.replace("/", "_")
        publisher = self.node.create_publisher(interface(type), topic, 1)
        try:
            for _ in range(200):
                own = [i for i in self.node.get_publishers_info_by_topic(topic) if i.node_name == self.node.get_name()]
                if own:
                    return str(own[0].topic_type_hash)
                time.sleep(0.01)
            raise TimeoutError(f"own publisher of {type} not in the graph")
        finally:
            self.node.destroy_publisher(publisher)

    def service_endpoints(self, service, type, timeout=10.0):
        """The type hashes rmw_fastrtps reads on `service`'s DDS topics (rq/…Request,
        rr/…Reply): {"client": [request writer, reply reader], "server": [request reader,
        reply writer]}, the client being this node's own, the server the first other one."""
        client = self.node.create_client(interface(type), service)
        me = self.node.get_name()
        try:
            if not client.wait_for_service(timeout_sec=timeout):
                raise TimeoutError(f"no server for {service} within {timeout} s")
            deadline = time.monotonic() + timeout
            while True:
                request = self.endpoints("rq" + service + "Request", no_mangle=True)
                reply = self.endpoints("rr" + service + "Reply", no_mangle=True)
                sides = {
                    "client": [[e["type_hash"] for e in request["publishers"] if e["node_name"] == me],
                               [e["type_hash"] for e in reply["subscriptions"] if e["node_name"] == me]],
                    "server": [[e["type_hash"] for e in request["subscriptions"] if e["node_name"] != me],
                               [e["type_hash"] for e in reply["publishers"] if e["node_name"] != me]],
                }
                if all(all(found) for found in sides.values()) or time.monotonic() > deadline:
                    return {side: [found[0] if found else None for found in both] for side, both in sides.items()}
                time.sleep(0.05)
        finally:
            self.node.destroy_client(client)

    def now(self):
        return time.monotonic()


def main():
    name = sys.argv[1] if len(sys.argv) > 1 else "rclpy_peer"
    rclpy.init()
    node = rclpy.create_node(name)
    created = time.monotonic()
    executor = MultiThreadedExecutor(num_threads=2)
    executor.add_node(node)
    threading.Thread(target=executor.spin, daemon=True).start()
    peer = Peer(node)
    print(json.dumps({"ok": {"rmw": rclpy.get_rmw_implementation_identifier(), "name": name, "created": created}}),
          flush=True)
    for line in sys.stdin:
        if not line.strip():
            continue
        request = json.loads(line)
        op = request.pop("op")
        try:
            answer = {"ok": getattr(peer, op)(**request)}
        except Exception as e:  # reported to the test, which fails with it
            answer = {"error": f"{type(e).__name__}: {e}"}
        print(json.dumps(answer), flush=True)
    executor.shutdown()
    node.destroy_node()
    rclpy.shutdown()


if __name__ == "__main__":
    main()
