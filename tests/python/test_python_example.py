"""`examples/python/im_reach.py`, a user's own reaching node in rclpy (on rmw_fastrtps_cpp,
under the Jazzy and the Kilted wheels), drives the live simulator node with actions from the
live trainer node's inverse model (issue 17, item 3; issue 38, item 3). It runs the
controller `causal-arm reach --controller im` runs in process, so on targets the in-process
loop reaches quickly (before any babbled step), the example over DDS must reach them too,
within a few steps of the same count."""

import json
import os
import subprocess

import pytest

from conftest import REPO_ROOT, node_process
from rclpy_peer import DISTROS, distro_env_script

EXAMPLE = REPO_ROOT / "examples" / "python" / "im_reach.py"
DOMAIN = "57"


def run_example(distro, args, env, timeout):
    """The example as a user runs it: in a shell that sourced the ROS 2 setup and the workspace."""
    command = f'source "{distro_env_script(distro)}" && exec python3 "{EXAMPLE}" ' + " ".join(map(str, args))
    return subprocess.run(["bash", "-c", command], env=env, capture_output=True, text=True, timeout=timeout)


@pytest.fixture(scope="module")
def quick_targets(run_cli, tmp_path_factory):
    """An IM trained on exp1, and targets the in-process IM controller reaches within 20 steps."""
    d = tmp_path_factory.mktemp("example")
    bag, models = d / "bag", d / "models"
    r = run_cli("generate", "exp1", "--steps", "100000", "--seed", "11", "--out", bag, timeout=300)
    assert r.returncode == 0, r.stderr
    r = run_cli("train", "--bag", bag, "--model", "im-mono", "--epochs", "30", "--max-folds", "1",
                "--cache", d / "cache", "--out", models, timeout=900)
    assert r.returncode == 0, r.stderr
    r = run_cli("reach", "exp1", "--controller", "im", "--model-dir", models, "--targets", "12", "--seed", "1",
                "--out", d / "reach", timeout=300)
    assert r.returncode == 0, r.stderr
    episodes = json.loads((d / "reach" / "report.json").read_text())["episodes"]
    quick = [e for e in episodes if e["within_1cm_at"] is not None and e["within_1cm_at"] < 20][:2]
    assert quick, f"the in-process IM controller reached no target within 20 steps: {episodes}"
    return models, quick


@pytest.mark.parametrize("distro", DISTROS)
def test_the_rclpy_example_reaches_targets_with_the_trainers_inverse_model(
        distro, quick_targets, causal_arm_bin, private_netns):
    models, quick = quick_targets
    env = dict(os.environ, RMW_IMPLEMENTATION="rmw_fastrtps_cpp", ROS_DOMAIN_ID=DOMAIN)
    budget = 40
    # Only an IM was trained: it also takes the forward model's place, which this loop never asks.
    trainer_args = ["-p", f"model_dir:={models}", "-p", "forward_model:=im-mono"]
    with node_process(causal_arm_bin.parent / "causal_arm_trainer", trainer_args, env) as trainer:
        for episode in quick:
            # A fresh simulator per target starts the arm at home, as each in-process episode does.
            sim_args = ["-p", "experiment:=exp1", "-p", f"steps:={budget + 1}", "-p", "wait_for_recorder:=false",
                        "-p", "trusted_publishers:=*"]
            with node_process(causal_arm_bin.parent / "causal_arm_sim", sim_args, env) as sim:
                run = run_example(distro, ["--target", *episode["target"], "--steps-per-target", budget,
                                           "--step", "0.05"], env, timeout=180)
                assert run.returncode == 0, f"{run.stderr[-3000:]}\nsimulator:\n{sim.log()[-3000:]}\ntrainer:\n{trainer.log()[-2000:]}"
            reached = json.loads(run.stdout)["targets"][0]
            assert reached["within_1cm_at"] is not None, (reached, episode)
            # The example counts the state it is given (step k sees the effect of k actions).
            assert abs(reached["within_1cm_at"] - episode["within_1cm_at"]) <= 3, (reached, episode)


def test_the_example_says_what_is_missing_when_no_trainer_runs(private_netns):
    env = dict(os.environ, ROS_DOMAIN_ID="58")
    run = run_example("jazzy", ["--target", "0.4", "0.2", "0.9", "--timeout", "2"], env, timeout=60)
    assert run.returncode != 0
    assert "/trainer/predict_action has no server: is the trainer node running?" in run.stderr, run.stderr
