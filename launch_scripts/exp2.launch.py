"""Experiment 2 data-generation graph: `ros2 launch launch_scripts/exp2.launch.py seed:=1 out:=bags/exp2`.

Same graph as `causal-arm launch exp2` (which needs no ROS 2 install)."""

import pathlib
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from _graph import graph  # noqa: E402


def generate_launch_description():
    return graph("exp2", "bags/exp2")
