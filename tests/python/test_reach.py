"""`causal-arm reach`: controllers drive the simulated arm to reachable targets (issue 17).
Over DDS (simulator, recorder and reacher nodes, a trainer node serving the IM) by default,
or in process. The Jacobian baseline must reach; babbling must not; a learned IM runs
through the same loop and is reported beside them; the DDS run and the in-process one
agree episode for episode, and the recorded bag holds every step."""

import json
import pathlib

import numpy as np
import pytest
from rosbags.highlevel import AnyReader

REPO = pathlib.Path(__file__).resolve().parents[2]
TINY_MODEL = REPO / "tests" / "corpus" / "trainer_model"


def _run(run_cli, out, *args):
    r = run_cli("reach", "exp1", "--targets", "20", "--seed", "3", *args, "--out", out, "--overwrite", timeout=300)
    assert r.returncode == 0, r.stderr
    report = json.loads((out / "report.json").read_text())
    assert len(report["episodes"]) == 20
    return report


def _reach(run_cli, tmp_path, *args):
    return _run(run_cli, tmp_path / "reach", *args)["summary"]


@pytest.mark.parametrize("controller", [["--controller", "jacobian"],
                                        ["--controller", "im", "--model-dir", TINY_MODEL, "--max-steps", "30"],
                                        ["--controller", "fm-mpc", "--model-dir", TINY_MODEL, "--max-steps", "20",
                                         "--samples", "16", "--iterations", "2"]])
def test_over_dds_the_nodes_reach_exactly_as_in_process(run_cli, tmp_path, controller):
    """The reacher node (asking the trainer node over DDS for the IM) and the library loop
    give the same episodes, and the recorder's bag holds every step of the run: per target
    max_steps + 1 states, the arm held still once within 5 mm."""
    dds = _run(run_cli, tmp_path / "dds", *controller)
    local = _run(run_cli, tmp_path / "local", *controller, "--in-process")
    assert dds["over"] == "dds" and local["over"] == "process"
    assert dds["episodes"] == local["episodes"]
    assert dds["summary"] == local["summary"]
    per_episode = dds["max_steps"] + 1
    with AnyReader([tmp_path / "dds" / "bag"]) as bag:
        actions = [bag.deserialize(raw, c.msgtype) for c, _, raw in
                   bag.messages(connections=[c for c in bag.connections if c.topic == "/babbler/action"])]
    assert len(actions) == 20 * per_episode
    for i, episode in enumerate(dds["episodes"]):
        steps = actions[i * per_episode:(i + 1) * per_episode]
        assert [a.step for a in steps] == list(range(per_episode))
        held = steps[episode["steps"]:]
        assert held and all(np.allclose(a.joint_deltas, 0.0) for a in held), episode
        if episode["within_5mm_at"] is None:
            assert len(held) == 1  # the last state's action, whose outcome is the next reset


def test_the_jacobian_controller_reaches_and_babbling_does_not(run_cli, tmp_path):
    jacobian = _reach(run_cli, tmp_path, "--controller", "jacobian")
    assert jacobian["success_1cm"] >= 0.9 and jacobian["success_5mm"] >= 0.9, jacobian
    assert jacobian["final_error_p10_p50_p90"][1] <= 0.005, jacobian
    random = _reach(run_cli, tmp_path, "--controller", "random")
    assert random["success_1cm"] <= 0.3, random


def test_targets_of_ones_own_are_reached(run_cli, tmp_path):
    out = tmp_path / "own"
    r = run_cli("reach", "exp1", "--target", "0.4", "0.2", "0.9", "--target", "-0.3", "-0.3", "1.0", "--out", out)
    assert r.returncode == 0, r.stderr
    report = json.loads((out / "report.json").read_text())
    assert [e["target"] for e in report["episodes"]] == [[0.4, 0.2, 0.9], [-0.3, -0.3, 1.0]]
    assert report["summary"]["success_5mm"] == 1.0, report["summary"]


def test_a_learned_inverse_model_drives_the_same_loop(run_cli, tmp_path):
    im = _reach(run_cli, tmp_path, "--controller", "im", "--model-dir", TINY_MODEL, "--max-steps", "50")
    assert im["controller"] == "im" and 0.0 <= im["success_1cm"] <= 1.0


def test_fm_mpc_reports_its_planner_beside_the_episodes(run_cli, tmp_path):
    """The CEM settings, the decisions with their time, and per target how far the FM's
    prediction of the executed action missed the observed effector."""
    report = _run(run_cli, tmp_path / "mpc", "--controller", "fm-mpc", "--model-dir", TINY_MODEL,
                  "--max-steps", "20", "--horizon", "2", "--in-process")
    planner = report["controller"]
    assert planner["cem"]["horizon"] == 2 and planner["cem"]["samples"] == 64
    log = planner["log"]
    assert log["decisions"] == sum(e["steps"] for e in report["episodes"])
    assert log["decision_seconds"] > 0
    errors = log["prediction_error_per_target"]
    assert len(errors) == 20 and all(e is None or e >= 0 for e in errors)


@pytest.mark.parametrize("args,message", [
    (["exp1", "--controller", "im"], "--controller im needs --model-dir"),
    (["exp1", "--controller", "im", "--model-dir", "NOPE"], "NOPE"),
    (["exp1", "--controller", "im", "--model-dir", TINY_MODEL, "--inverse-model", "fm"], "not an exp1 inverse model"),
    (["exp1", "--targets", "0"], "--targets must be a positive number, got 0"),
    (["exp1", "--step", "-0.1"], "--step must be a positive number of metres"),
    (["exp2", "--controller", "im", "--model-dir", TINY_MODEL], "holds exp1 models; this task drives exp2"),
    (["exp1", "--target", "3", "0", "1"], "--target 3 0 1: out of the arm's reach: target (3.0000, 0.0000, 1.0000) m is unreachable"),
    (["exp1", "--target", "0.4", "0.2"], "3 values required"),
    (["exp1", "--max-steps", "0"], "--max-steps must be a positive number, got 0"),
    (["exp1", "--controller", "fm-mpc"], "--controller fm-mpc needs --model-dir"),
    (["exp1", "--controller", "fm-mpc", "--model-dir", TINY_MODEL, "--forward-model", "nope"],
     "no forward model \"nope\""),
    (["exp1", "--controller", "fm-mpc", "--model-dir", TINY_MODEL, "--forward-model", "im-mono"],
     "is an inverse model, not a forward model"),
    (["exp1", "--controller", "fm-mpc", "--model-dir", TINY_MODEL, "--elites", "99"],
     "CEM elites must be between 1 and the samples (64), got 99"),
])
def test_bad_reach_options_are_refused(run_cli, tmp_path, args, message):
    r = run_cli("reach", *args, "--out", tmp_path / "out")
    assert r.returncode != 0 and message in r.stderr, r.stderr


def test_a_bag_of_an_earlier_run_is_kept_unless_overwrite_is_given(run_cli, tmp_path):
    out = tmp_path / "reach"
    assert run_cli("reach", "exp1", "--targets", "1", "--max-steps", "5", "--out", out).returncode == 0
    r = run_cli("reach", "exp1", "--targets", "1", "--max-steps", "5", "--out", out)
    assert r.returncode != 0 and "already holds a bag" in r.stderr and "--overwrite" in r.stderr, r.stderr


@pytest.fixture(scope="module")
def exp2_models(tmp_path_factory, run_cli):
    """A small exp 2 FM and IM (4 episodes, 2 epochs): enough to drive the exp 2 layout."""
    d = tmp_path_factory.mktemp("exp2_models")
    r = run_cli("generate", "exp2", "--profile", "quick", "--episodes", "4", "--seed", "3", "--out", d / "bag")
    assert r.returncode == 0, r.stderr
    for model in ("fm", "im-mono"):
        r = run_cli("train", "--bag", d / "bag", "--model", model, "--profile", "quick", "--epochs", "2",
                    "--folds", "2", "--max-folds", "1", "--out", d / "models", "--cache", d / "cache", timeout=300)
        assert r.returncode == 0, r.stderr
    return d / "models"


@pytest.mark.parametrize("controller", ["jacobian", "im", "fm-mpc"])
def test_exp2_reaching_runs_over_dds_exactly_as_in_process(run_cli, tmp_path, exp2_models, controller):
    """Exp 2: targets above the table; the IM and FM are asked with exp 2's 23-feature state
    (cube, effector orientation, magnet), over DDS as in process."""
    args = ["--controller", controller, "--model-dir", exp2_models, "--max-steps", "15",
            "--samples", "16", "--iterations", "2"]
    runs = {}
    for where, extra in (("dds", []), ("local", ["--in-process"])):
        r = run_cli("reach", "exp2", "--targets", "6", "--seed", "2", *args, *extra, "--out", tmp_path / where,
                    timeout=300)
        assert r.returncode == 0, r.stderr
        runs[where] = json.loads((tmp_path / where / "report.json").read_text())
    assert runs["dds"]["episodes"] == runs["local"]["episodes"]
    for e in runs["dds"]["episodes"]:
        x, y, z = e["target"]
        assert abs(x - 0.58) <= 0.2 and abs(y) <= 0.3 and 0.25 <= z <= 0.5, e
    if controller == "jacobian":
        assert runs["dds"]["summary"]["success_5mm"] == 1.0, runs["dds"]["summary"]


def test_fm_mpc_places_the_cube_over_dds_exactly_as_in_process(run_cli, tmp_path, exp2_models):
    """`place`: pick the cube with the magnet, carry it over a spot, release it; the reacher
    node (task:=place, asking the trainer node's FM) and the library loop agree trial for
    trial, and every trial is reported with where the cube came to rest."""
    reports = {}
    for where, extra in (("dds", []), ("local", ["--in-process"])):
        r = run_cli("place", "--trials", "3", "--seed", "1", "--model-dir", exp2_models, "--max-steps", "60",
                    "--samples", "16", "--iterations", "2", *extra, "--out", tmp_path / where, timeout=300)
        assert r.returncode == 0, r.stderr
        reports[where] = json.loads((tmp_path / where / "report.json").read_text())
    dds, local = reports["dds"], reports["local"]
    assert dds["over"] == "dds" and local["over"] == "process"
    assert dds["trials"] == local["trials"] and dds["summary"] == local["summary"]
    assert dds["summary"]["trials"] == 3 and len(dds["trials"]) == 3
    for t in dds["trials"]:
        assert t["steps"] <= 60 and t["final_distance"] >= 0 and 0.1 < t["spot"][0] < 1.0, t
        assert t["released_at"] is None or t["held_at"] is not None, t
    assert dds["planner"]["cem"]["samples"] == 16
    with AnyReader([tmp_path / "dds" / "bag"]) as bag:
        actions = [c for c in bag.connections if c.topic == "/babbler/action"]
        assert sum(c.msgcount for c in actions) == 3 * 61


@pytest.mark.parametrize("args,message", [
    (["--trials", "0"], "--trials and --max-steps must be positive numbers, got 0 and 400"),
    (["--model-dir", TINY_MODEL], "holds exp1 models; this task drives exp2"),
    (["--model-dir", "NOPE"], "NOPE"),
])
def test_bad_place_options_are_refused(run_cli, tmp_path, args, message):
    base = {"--model-dir": str(tmp_path)}
    base.update(dict(zip(args[::2], args[1::2])))
    r = run_cli("place", *[x for kv in base.items() for x in kv], "--out", tmp_path / "out")
    assert r.returncode != 0 and message in r.stderr, r.stderr
