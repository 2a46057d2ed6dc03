"""Shared builder of the causal-arm data-generation graph for `ros2 launch`.

The node binaries (causal_arm_sim, causal_arm_babbler, causal_arm_recorder) are looked up
on PATH or in CAUSAL_ARM_BIN_DIR (default: <repo>/target/release). Launch arguments mirror
`causal-arm launch`: profile, steps, episodes, seed, sigma, velocity_scale,
move_while_switching, out, overwrite.
"""

import os
import pathlib

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, EmitEvent, RegisterEventHandler
from launch.actions import ExecuteProcess
from launch.event_handlers import OnProcessExit
from launch.events import Shutdown
from launch.substitutions import LaunchConfiguration

REPO = pathlib.Path(__file__).resolve().parents[1]


def _binary(name: str) -> str:
    directory = os.environ.get("CAUSAL_ARM_BIN_DIR", str(REPO / "target" / "release"))
    candidate = pathlib.Path(directory) / name
    return str(candidate) if candidate.exists() else name


def graph(experiment: str, default_out: str) -> LaunchDescription:
    args = {
        "profile": "quick",
        "steps": "0",
        "episodes": "0",
        "seed": "0",
        "sigma": "0.35",
        "velocity_scale": "1.0",
        "move_while_switching": "true",
        "out": default_out,
        "overwrite": "false",
    }
    declared = [DeclareLaunchArgument(k, default_value=v) for k, v in args.items()]

    def params(*extra):
        items = ["experiment:=" + experiment]
        for key in ("profile", "steps", "episodes", "seed", "sigma", "velocity_scale",
                    "move_while_switching"):
            items.append([key, ":=", LaunchConfiguration(key)])
        items.extend(extra)
        out = ["--ros-args"]
        for item in items:
            out += ["-p", item]
        return out

    recorder = ExecuteProcess(
        cmd=[_binary("causal_arm_recorder"),
             *params(["output:=", LaunchConfiguration("out")], ["overwrite:=", LaunchConfiguration("overwrite")])],
        output="screen", name="causal_arm_recorder")
    babbler = ExecuteProcess(cmd=[_binary("causal_arm_babbler"), *params()], output="screen",
                             name="causal_arm_babbler")
    sim = ExecuteProcess(cmd=[_binary("causal_arm_sim"), *params()], output="screen", name="causal_arm_sim")
    # When the recorder has written the bag, shut the graph down.
    done = RegisterEventHandler(OnProcessExit(target_action=recorder, on_exit=[EmitEvent(event=Shutdown())]))
    return LaunchDescription([*declared, recorder, babbler, sim, done])
