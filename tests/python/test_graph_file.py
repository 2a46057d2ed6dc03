"""The graph is described once (launch_scripts/graph.toml): `causal-arm launch`, `causal-arm
generate`'s defaults and the ros2 launch files' node commands all follow it, so changing a
default there changes every front end. No DDS is started: `launch --print-commands` only
prints the commands it would run."""

import importlib.util
import pathlib
import re
import tomllib

import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]
GRAPH = REPO / "launch_scripts" / "graph.toml"


def load_launch_module():
    spec = importlib.util.spec_from_file_location("_graph", REPO / "launch_scripts" / "_graph.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def with_sigma(tmp_path, sigma: str) -> pathlib.Path:
    text = GRAPH.read_text()
    changed = re.sub(r'(name = "sigma"\ndefault = )[0-9.]+', r"\g<1>" + sigma, text)
    assert changed != text
    path = tmp_path / "graph.toml"
    path.write_text(changed)
    return path


def sigma_of(args: list) -> str:
    flat = ["".join(map(str, a)) if isinstance(a, list) else a for a in args]
    found = [a.split(":=")[1] for a in flat if a.startswith("sigma:=")]
    assert len(found) == 1, flat
    return found[0]


def test_every_front_end_takes_sigma_from_the_graph_file(run_cli, tmp_path, monkeypatch):
    default = next(p["default"] for p in tomllib.loads(GRAPH.read_text())["run_params"]
                   if p["name"] == "sigma")
    for graph, sigma in [(None, str(default)), (with_sigma(tmp_path, "0.123"), "0.123")]:
        env = {"CAUSAL_ARM_GRAPH": str(graph)} if graph else {}
        if graph:
            monkeypatch.setenv("CAUSAL_ARM_GRAPH", str(graph))
        else:
            monkeypatch.delenv("CAUSAL_ARM_GRAPH", raising=False)
        # causal-arm launch: every node gets the file's sigma.
        out = run_cli("launch", "exp1", "--out", tmp_path / "bag", "--print-commands", env=env)
        assert out.returncode == 0, out.stderr
        lines = out.stdout.strip().splitlines()
        names = [line.split()[0] for line in lines]
        assert names == ["causal_arm_recorder", "causal_arm_babbler", "causal_arm_sim"]
        assert all(sigma_of(line.split()[1:]) == sigma for line in lines), lines
        # causal-arm generate: the file's sigma is the option's default.
        help_text = run_cli("generate", "--help", env=env).stdout
        assert re.search(r"--sigma <SIGMA>[^\[]*\[default: " + re.escape(sigma) + r"\]", help_text)
        # ros2 launch files: the same nodes, with the file's sigma as the argument default.
        launch = load_launch_module()
        spec = launch.load_graph()
        args = launch.launch_arguments(spec, "bags/x")
        assert args["sigma"] == sigma
        commands = launch.node_commands("exp1", args, spec)
        assert [name for name, _ in commands] == names
        assert all(sigma_of(cmd) == sigma for _, cmd in commands)
        recorder = dict(commands)["causal_arm_recorder"]
        assert ["output", ":=", "bags/x"] in recorder


def test_a_bad_graph_file_is_named(run_cli, tmp_path):
    bad = tmp_path / "graph.toml"
    bad.write_text(GRAPH.read_text().replace('default = 0.35', 'default = 20.0'))
    out = run_cli("generate", "--help", env={"CAUSAL_ARM_GRAPH": str(bad)})
    assert out.returncode != 0
    assert f"error: graph file {bad}: node " in out.stderr, out.stderr
    assert "parameter sigma: default 20 outside its range [0, 10]" in out.stderr


def test_a_seed_beyond_int64_gets_one_verdict_from_the_cli_and_every_node(run_cli, causal_arm_bin, tmp_path, private_netns):
    """The seed is an int64 ROS parameter of every node: `generate` and `launch` refuse what
    the nodes would refuse, with the nodes' own words, before any work starts (launch used
    to accept it and fail inside the nodes)."""
    import subprocess
    seed = str(2**64 - 1)
    message = f'parameter "seed" = {seed} is outside its range [0, {2**63 - 1}]'
    for command in (["generate", "exp1", "--steps", "10"], ["launch", "exp1", "--steps", "10"]):
        r = run_cli(*command, "--seed", seed, "--out", tmp_path / "bag")
        assert r.returncode != 0 and message in r.stderr, r.stderr
        assert not (tmp_path / "bag").exists()
    for node in ("causal_arm_sim", "causal_arm_babbler", "causal_arm_recorder"):
        r = subprocess.run([str(causal_arm_bin.parent / node), "--ros-args", "-p", f"seed:={seed}"],
                           capture_output=True, text=True, timeout=60)
        assert r.returncode != 0 and message in r.stderr, (node, r.stderr)
    # The largest seed both take is the same one.
    r = run_cli("generate", "exp1", "--steps", "10", "--seed", str(2**63 - 1), "--out", tmp_path / "ok")
    assert r.returncode == 0, r.stderr


def chunk_compressions(bag: pathlib.Path) -> set:
    """The compression of every chunk of a bag's files, read by the `mcap` package."""
    from mcap.records import Chunk
    from mcap.stream_reader import StreamReader

    found = set()
    for path in sorted(bag.glob("*.mcap")):
        with open(path, "rb") as f:
            found |= {r.compression for r in StreamReader(f, emit_chunks=True).records
                      if isinstance(r, Chunk)}
    return found


def test_a_parameter_added_to_the_graph_file_reaches_the_cli_and_the_launch_files(run_cli, tmp_path):
    """The recorder's chunk_compression was added as one entry in graph.toml plus its use
    (the recorder hands it to the bag writer): `generate` and `launch` take its default and
    its one check from the file, `launch` passes it to the recorder, and the ros2 launch
    files declare it as an argument and pass it on. (The node's side, `ros2 param
    describe`, is in test_rclpy.py.)"""
    (decl,) = [p for n in tomllib.loads(GRAPH.read_text())["nodes"] if n["name"] == "causal_arm_recorder"
               for p in n["params"] if p["name"] == "chunk_compression"]
    assert decl["default"] == "zstd" and decl["choices"] == ["zstd", "lz4", "none"]
    help_text = run_cli("generate", "--help").stdout
    assert re.search(r"--chunk-compression <CHUNK_COMPRESSION>[^\[]*\[default: zstd\]", help_text), help_text
    sizes = {}
    for choice, written in (("zstd", {"zstd"}), ("lz4", {"lz4"}), ("none", {""})):
        bag = tmp_path / choice
        r = run_cli("generate", "exp1", "--steps", "300", "--chunk-compression", choice, "--out", bag)
        assert r.returncode == 0, r.stderr
        assert chunk_compressions(bag) == written
        sizes[choice] = sum(f.stat().st_size for f in bag.glob("*.mcap"))
    assert sizes["zstd"] < sizes["none"] and sizes["lz4"] < sizes["none"], sizes
    r = run_cli("generate", "exp1", "--steps", "10", "--chunk-compression", "brotli", "--out", tmp_path / "x")
    assert r.returncode != 0 and 'unknown chunk compression "brotli": expected zstd, lz4 or none' in r.stderr
    # causal-arm launch: the recorder, and only it, is given the setting.
    out = run_cli("launch", "exp1", "--out", tmp_path / "bag", "--chunk-compression", "lz4", "--print-commands")
    assert out.returncode == 0, out.stderr
    given = {line.split()[0]: "chunk_compression:=lz4" in line.split() for line in out.stdout.strip().splitlines()}
    assert given == {"causal_arm_recorder": True, "causal_arm_babbler": False, "causal_arm_sim": False}
    # ros2 launch files: an argument with the file's default, passed to the recorder.
    launch = load_launch_module()
    spec = launch.load_graph()
    args = launch.launch_arguments(spec, "bags/x")
    assert args["recorder_chunk_compression"] == "zstd"
    commands = dict(launch.node_commands("exp1", {**args, "recorder_chunk_compression": "none"}, spec))
    assert ["chunk_compression", ":=", "none"] in commands["causal_arm_recorder"]
    assert not any(item[0] == "chunk_compression" for item in commands["causal_arm_sim"] if isinstance(item, list))


def test_the_recorder_refuses_an_unknown_compression_before_any_work(causal_arm_bin, tmp_path, private_netns):
    import subprocess
    r = subprocess.run([str(causal_arm_bin.parent / "causal_arm_recorder"), "--ros-args",
                        "-p", f"output:={tmp_path / 'bag'}", "-p", "chunk_compression:=brotli"],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode != 0 and 'unknown chunk compression "brotli": expected zstd, lz4 or none' in r.stderr, r.stderr
    assert not (tmp_path / "bag").exists()


def test_kappa_0_gets_one_verdict_from_the_cli_and_the_node(run_cli, causal_arm_bin, private_netns):
    """`--kappa 0` and `-p kappa:=0` are checked by the one check of the explainer's kappa,
    before anything is read: no model or bag exists here."""
    import subprocess
    message = 'parameter "kappa" = 0 is outside its range [0.000001, 1000000]'
    r = run_cli("explain", "--model", "no-model", "--bag", "no-bag", "--kappa", "0")
    assert r.returncode != 0 and message in r.stderr, r.stderr
    r = subprocess.run([str(causal_arm_bin.parent / "causal_arm_explainer"), "--ros-args",
                        "-p", "model_dir:=no-model", "-p", "bag:=no-bag", "-p", "kappa:=0"],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode != 0 and message in r.stderr, r.stderr
