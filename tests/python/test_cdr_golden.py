"""Golden CDR tests: our generated Rust types against the independent `rosbags` implementation.

For every type `cdr-tool list` knows (standard ROS 2 types and our own msgs/srv halves) we build
a non-trivial sample value (non-empty arrays, odd-length and non-ASCII strings so alignment
padding is exercised, negative integers), serialise it with rosbags' CDR serializer (types from
the ROS 2 Jazzy store plus our .msg/.srv files), encode the same value as JSON through
`cdr-tool encode`, and require identical bytes; then `cdr-tool decode` must read rosbags' bytes
back to the same value. Also checks that the vendored standard .msg files match Jazzy, that the
`definition` text (as written into MCAP) parses in rosbags, and that every .msg/.srv file is
covered. Build first: `cargo build -p causal_arm_msgs --bins`.
"""

import json
import os
import pathlib
import subprocess

import numpy as np
import pytest
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.base import Nodetype

NUMPY_DTYPES = {
    "bool": np.bool_,
    "byte": np.uint8,
    "char": np.uint8,
    "int8": np.int8,
    "uint8": np.uint8,
    "int16": np.int16,
    "uint16": np.uint16,
    "int32": np.int32,
    "uint32": np.uint32,
    "int64": np.int64,
    "uint64": np.uint64,
    "float32": np.float32,
    "float64": np.float64,
}


@pytest.fixture(scope="session")
def cdr_tool(repo_root) -> pathlib.Path:
    target = pathlib.Path(os.environ.get("CARGO_TARGET_DIR", repo_root / "target"))
    path = target / "debug" / "cdr-tool"
    if not path.exists():
        pytest.fail(f"{path} does not exist: run `cargo build -p causal_arm_msgs --bins` first")
    return path


def run_tool(tool, *args, stdin=None) -> str:
    proc = subprocess.run([str(tool), *args], input=stdin, capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, f"cdr-tool {' '.join(args)} failed: {proc.stderr}"
    return proc.stdout.strip()


def split_srv(text: str) -> tuple[str, str]:
    lines = text.splitlines(keepends=True)
    sep = [i for i, line in enumerate(lines) if line.strip() == "---"]
    assert len(sep) == 1, "a .srv needs exactly one --- line"
    return "".join(lines[: sep[0]]), "".join(lines[sep[0] + 1 :])


@pytest.fixture(scope="session")
def own_files(repo_root):
    msgs = repo_root / "msgs"
    return sorted((msgs / "msg").glob("*.msg")), sorted((msgs / "srv").glob("*.srv"))


@pytest.fixture(scope="session")
def typestore(own_files, repo_root):
    """rosbags' Jazzy store plus our messages and the service halves (ours and the vendored
    standard ones, which rosbags' store lacks)."""
    store = get_typestore(Stores.ROS2_JAZZY)
    msg_files, srv_files = own_files
    types = {}
    for path in msg_files:
        types.update(get_types_from_msg(path.read_text(), f"causal_arm_msgs/msg/{path.stem}"))
    standard_srv = sorted((repo_root / "msgs" / "ros_interfaces").glob("*/srv/*.srv"))
    for path in srv_files + standard_srv:
        package = "causal_arm_msgs" if path in srv_files else path.parts[-3]
        request, response = split_srv(path.read_text())
        for half, text in (("Request", request), ("Response", response)):
            # rosbags' .msg parser files every name under `msg`; services halves live under `srv`.
            parsed = get_types_from_msg(text, f"{package}/msg/{path.stem}_{half}")
            types[f"{package}/srv/{path.stem}_{half}"] = parsed.pop(f"{package}/msg/{path.stem}_{half}")
            types.update(parsed)
    store.register(types)
    return store


@pytest.fixture(scope="session")
def tool_types(cdr_tool) -> list[str]:
    return run_tool(cdr_tool, "list").splitlines()


class Sampler:
    """Deterministic, varied sample values as (rosbags object, JSON value) pairs."""

    def __init__(self, store):
        self.store = store
        self.k = 0

    def tick(self) -> int:
        self.k += 1
        return self.k

    def scalar(self, typename: str, bound: int = 0):
        k = self.tick()
        if typename == "bool":
            return k % 2 == 1
        if typename in ("string", "wstring"):
            # Odd and even byte lengths, non-ASCII, sometimes empty, within a bound if any.
            choices = ["", "a", "é", "ab→c", "tf ü", "odd_len", "Ωmega", "x" * 5]
            s = choices[k % len(choices)]
            return s[:bound] if bound else s
        if typename.startswith("float"):
            return -3.25 + 0.75 * k  # exactly representable in float32 too
        if typename.startswith("int"):
            bits = int(typename[3:])
            return -((k * 37) % (2 ** (bits - 1))) or -1
        if typename.startswith("uint") or typename in ("byte", "char"):
            bits = 8 if typename in ("byte", "char") else int(typename[4:])
            return (k * 53 + 1) % (2**bits)
        raise AssertionError(f"unhandled primitive {typename}")

    def value(self, desc):
        kind, detail = desc
        if kind == Nodetype.BASE:
            typename, bound = detail
            v = self.scalar(typename, bound)
            return v, v
        if kind == Nodetype.NAME:
            return self.message(detail)
        if kind in (Nodetype.ARRAY, Nodetype.SEQUENCE):
            sub, length = detail
            if kind == Nodetype.ARRAY:
                n = length
            else:
                n = min(3, length) if length else 3
            pairs = [self.value(sub) for _ in range(n)]
            py = [p for p, _ in pairs]
            js = [j for _, j in pairs]
            if sub[0] == Nodetype.BASE and sub[1][0] in NUMPY_DTYPES:
                py = np.array(py, dtype=NUMPY_DTYPES[sub[1][0]])
            return py, js
        raise AssertionError(f"unhandled node type {kind}")

    def message(self, name: str):
        _consts, fields = self.store.fielddefs[name]
        py, js = {}, {}
        for fname, desc in fields:
            py[fname], js[fname] = self.value(desc)
        return self.store.types[name](**py), js


def normalize(value):
    """JSON-comparable form of a rosbags message or our JSON."""
    if hasattr(value, "__dataclass_fields__"):
        return {k: normalize(getattr(value, k)) for k in value.__dataclass_fields__ if not k.startswith("__") and not k.isupper()}
    if isinstance(value, np.ndarray):
        return [normalize(v) for v in value.tolist()]
    if isinstance(value, dict):
        return {k: normalize(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [normalize(v) for v in value]
    if isinstance(value, (np.generic,)):
        return value.item()
    return value


def test_registry_covers_every_interface_file(own_files, tool_types, repo_root):
    msg_files, srv_files = own_files
    assert msg_files and srv_files
    expected = {f"causal_arm_msgs/msg/{p.stem}" for p in msg_files}
    for p in srv_files:
        expected |= {f"causal_arm_msgs/srv/{p.stem}_Request", f"causal_arm_msgs/srv/{p.stem}_Response"}
    for p in (repo_root / "msgs" / "ros_interfaces").glob("*/msg/*.msg"):
        expected.add(f"{p.parts[-3]}/msg/{p.stem}")
    missing = expected - set(tool_types)
    assert not missing, f"cdr-tool list lacks {sorted(missing)}"
    # And every type the graph relies on is there.
    for t in [
        "builtin_interfaces/msg/Time", "builtin_interfaces/msg/Duration", "std_msgs/msg/Header",
        "std_msgs/msg/String", "std_msgs/msg/ColorRGBA", "sensor_msgs/msg/JointState",
        "geometry_msgs/msg/Point", "geometry_msgs/msg/Quaternion", "geometry_msgs/msg/Pose",
        "geometry_msgs/msg/PoseStamped", "geometry_msgs/msg/Vector3", "geometry_msgs/msg/Transform",
        "geometry_msgs/msg/TransformStamped", "tf2_msgs/msg/TFMessage", "rosgraph_msgs/msg/Clock",
        "rcl_interfaces/msg/Log",
    ]:
        assert t in tool_types


def test_vendored_standard_msgs_match_jazzy(repo_root):
    jazzy = get_typestore(Stores.ROS2_JAZZY)
    files = sorted((repo_root / "msgs" / "ros_interfaces").glob("*/msg/*.msg"))
    assert len(files) >= 16
    for p in files:
        name = f"{p.parts[-3]}/msg/{p.stem}"
        consts, fields = get_types_from_msg(p.read_text(), name)[name]
        ref_consts, ref_fields = jazzy.fielddefs[name]
        # A message of constants only (rcl_interfaces/ParameterType) has no fields in
        # the .msg; rosbags' store spells rosidl's placeholder member out.
        fields = fields or EMPTY_MESSAGE_FIELDS
        assert fields == ref_fields, name
        # rosbags' store spells `byte` constants as uint8; same values either way.
        norm = lambda cs: [(n, "uint8" if t == "byte" else t, v) for n, t, v in cs]  # noqa: E731
        assert norm(consts) == norm(ref_consts), name


def test_golden_bytes_for_every_type(typestore, tool_types, cdr_tool):
    sampler = Sampler(typestore)
    checked = []
    for ros_type in tool_types:
        assert ros_type in typestore.fielddefs, f"{ros_type}: not in the rosbags typestore"
        for _variant in range(2):  # two different samples: shifts every alignment
            obj, js = sampler.message(ros_type)
            expected = bytes(typestore.serialize_cdr(obj, ros_type))
            ours = run_tool(cdr_tool, "encode", ros_type, stdin=json.dumps(js))
            assert ours == expected.hex(), (
                f"{ros_type}: CDR differs\n value: {js}\n rosbags: {expected.hex()}\n ours:    {ours}"
            )
            decoded = json.loads(run_tool(cdr_tool, "decode", ros_type, expected.hex()))
            assert decoded == normalize(js), f"{ros_type}: decode differs"
            back = typestore.deserialize_cdr(bytes.fromhex(ours), ros_type)
            if _has_byte_sequence(typestore, ros_type):
                # rosbags reads `byte[]` as int8 although it writes it from uint8 (ROS 2's
                # octet): check that what it read writes back our very bytes instead.
                assert bytes(typestore.serialize_cdr(back, ros_type)).hex() == ours, ros_type
            else:
                assert normalize(back) == normalize(js), f"{ros_type}: rosbags reads our bytes differently"
        checked.append(ros_type)
    assert len(checked) == len(tool_types) >= 28
    print(f"golden CDR identical for {len(checked)} types")


EMPTY_MESSAGE_FIELDS = [("structure_needs_at_least_one_member", (Nodetype.BASE, ("uint8", 0)))]


def _has_byte_sequence(store, name, seen=None):
    """Whether `name` has a `byte[]` field at any depth."""
    seen = seen if seen is not None else set()
    if name in seen:
        return False
    seen.add(name)
    for _field, (kind, detail) in store.fielddefs[name][1]:
        if kind in (Nodetype.ARRAY, Nodetype.SEQUENCE):
            kind, detail = detail[0]
            if kind == Nodetype.BASE and detail[0] == "byte":
                return True
        if kind == Nodetype.NAME and _has_byte_sequence(store, detail, seen):
            return True
    return False


def test_definitions_parse_in_rosbags(typestore, tool_types, cdr_tool):
    for ros_type in tool_types:
        text = run_tool(cdr_tool, "definition", ros_type)
        parsed = get_types_from_msg(text, ros_type.replace("/srv/", "/msg/"))
        parsed[ros_type] = parsed.pop(ros_type.replace("/srv/", "/msg/"))
        for name, fielddef in parsed.items():
            # A message of constants only: rosbags' store spells rosidl's placeholder out.
            fields = fielddef[1] or EMPTY_MESSAGE_FIELDS
            assert fields == typestore.fielddefs[name][1], f"{ros_type}: definition of {name} differs"
        if ros_type == "sensor_msgs/msg/JointState":
            assert text.count("MSG: std_msgs/Header") == 1
            assert text.count("MSG: builtin_interfaces/Time") == 1


def test_tool_errors_are_clear(cdr_tool):
    proc = subprocess.run([str(cdr_tool), "encode", "sensor_msgs/msg/JointStat"], input="{}",
                          capture_output=True, text=True)
    assert proc.returncode != 0 and "JointStat" in proc.stderr
    proc = subprocess.run([str(cdr_tool), "decode", "std_msgs/msg/String", "0001000005"],
                          capture_output=True, text=True)
    assert proc.returncode != 0 and "std_msgs/msg/String" in proc.stderr
    proc = subprocess.run([str(cdr_tool)], capture_output=True, text=True)
    assert proc.returncode != 0 and "usage" in proc.stderr
