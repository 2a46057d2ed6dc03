"""Shared builder of the causal-arm data-generation graph for `ros2 launch`.

The graph (nodes in start order, their parameters with defaults, which node ends the run)
is read from launch_scripts/graph.toml, the file `causal-arm launch`, `causal-arm
generate` and the nodes read too; CAUSAL_ARM_GRAPH=FILE replaces it for all of them.
Every run parameter of the file is a launch argument with the file's default; so is every
node's own parameter, named after its node (`recorder_chunk_compression:=lz4`,
`sim_ack_window:=64`), but for the recorder's `out` and `overwrite`. A parameter added to
the file is thus a launch argument without an edit here.

The node binaries are looked up on PATH or in CAUSAL_ARM_BIN_DIR (default:
<repo>/target/release).
"""

import os
import pathlib
import tomllib

REPO = pathlib.Path(__file__).resolve().parents[1]

# Launch arguments that set a node's own parameter: (argument, node parameter).
NODE_ARGUMENTS = {"causal_arm_recorder": [("out", "output"), ("overwrite", "overwrite")]}


def graph_file() -> pathlib.Path:
    return pathlib.Path(os.environ.get("CAUSAL_ARM_GRAPH", REPO / "launch_scripts" / "graph.toml"))


def load_graph() -> dict:
    with open(graph_file(), "rb") as f:
        return tomllib.load(f)


def ros_text(value) -> str:
    """A default as `-p name:=value` writes it (TOML booleans are lowercase in ROS too)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    return str(value)


def own_arguments(node: dict) -> list:
    """(launch argument, parameter, default text) of a node's own parameters."""
    named = dict((param, arg) for arg, param in NODE_ARGUMENTS.get(node["name"], []))
    short = node["name"].removeprefix("causal_arm_")
    return [(named.get(p["name"], f"{short}_{p['name']}"), p["name"], ros_text(p["default"]))
            for p in node.get("params", [])]


def launch_arguments(spec: dict, default_out: str) -> dict:
    """Launch argument name -> default text."""
    args = {p["name"]: ros_text(p["default"]) for p in spec["run_params"]}
    for node in spec["nodes"]:
        args.update({arg: default for arg, _, default in own_arguments(node)})
    args["out"] = default_out
    return args


def node_commands(experiment: str, values: dict, spec: dict = None) -> list:
    """(node name, ROS arguments) of every node in start order; `values` maps each launch
    argument to its value (text, or a launch substitution)."""
    spec = spec or load_graph()
    run = [p["name"] for p in spec["run_params"] if p["name"] != "experiment"]
    commands = []
    for node in spec["nodes"]:
        items = [["experiment:=", experiment]]
        items += [[name, ":=", values[name]] for name in run]
        items += [[param, ":=", values[arg]] for arg, param, _ in own_arguments(node)]
        args = ["--ros-args"]
        for item in items:
            args += ["-p", item]
        commands.append((node["name"], args))
    return commands


def _binary(name: str) -> str:
    directory = os.environ.get("CAUSAL_ARM_BIN_DIR", str(REPO / "target" / "release"))
    candidate = pathlib.Path(directory) / name
    return str(candidate) if candidate.exists() else name


def graph(experiment: str, default_out: str):
    """The LaunchDescription of the graph: the nodes of graph.toml with its defaults."""
    from launch import LaunchDescription
    from launch.actions import DeclareLaunchArgument, EmitEvent, ExecuteProcess
    from launch.actions import RegisterEventHandler
    from launch.event_handlers import OnProcessExit
    from launch.events import Shutdown
    from launch.substitutions import LaunchConfiguration

    spec = load_graph()
    args = launch_arguments(spec, default_out)
    declared = [DeclareLaunchArgument(k, default_value=v) for k, v in args.items()]
    values = {k: LaunchConfiguration(k) for k in args}
    actions = list(declared)
    ends_run = None
    for (name, ros_args), node in zip(node_commands(experiment, values, spec), spec["nodes"]):
        process = ExecuteProcess(cmd=[_binary(name), *ros_args], output="screen", name=name)
        actions.append(process)
        if node.get("ends_run"):
            ends_run = process
    # When the node that ends the run (the recorder, once the bag is written) exits, shut
    # the graph down.
    actions.append(RegisterEventHandler(OnProcessExit(target_action=ends_run,
                                                      on_exit=[EmitEvent(event=Shutdown())])))
    return LaunchDescription(actions)
