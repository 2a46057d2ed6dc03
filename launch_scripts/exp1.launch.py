"""Experiment 1 data-generation graph: `ros2 launch launch_scripts/exp1.launch.py seed:=1 out:=bags/exp1`.

Same graph as `causal-arm launch exp1` (which needs no ROS 2 install)."""

import pathlib
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from _graph import graph  # noqa: E402


def generate_launch_description():
    return graph("exp1", "bags/exp1")
