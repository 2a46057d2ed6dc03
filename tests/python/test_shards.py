"""`generate --shards N`: one run spread over the cores as a shard set of complete bags
that rosbags opens one by one and that train takes as one dataset (issue 17, item 4)."""

import json
import pathlib
import shutil

import pytest
import yaml
from rosbags.highlevel import AnyReader

from conftest import custom_data

SEED = 4


def _messages(bag: pathlib.Path) -> list:
    """Every message as (topic, log time, raw CDR), as rosbags reads them."""
    with AnyReader([bag]) as reader:
        return [(c.topic, t, bytes(raw)) for c, t, raw in reader.messages()]


@pytest.fixture(scope="module")
def shard_set(run_cli, tmp_path_factory):
    out = tmp_path_factory.mktemp("shards") / "set"
    r = run_cli("generate", "exp1", "--steps", "1201", "--seed", SEED, "--shards", "2", "--out", out)
    assert r.returncode == 0, r.stderr
    return out


def test_each_shard_is_a_complete_bag_naming_its_place_and_seed(shard_set):
    manifest = yaml.safe_load((shard_set / "shard_set.yaml").read_text())
    assert manifest["shards"] == ["shard-0", "shard-1"]
    assert manifest["custom_data"]["causal_arm.shard_set_seed"] == str(SEED)
    steps = []
    for i, name in enumerate(manifest["shards"]):
        data = custom_data(shard_set / name)
        assert data["causal_arm.shard"] == f"{i}/2"
        assert data["causal_arm.shard_set_seed"] == str(SEED)
        assert data["causal_arm.seed"] == manifest["custom_data"][f"causal_arm.seed.{name}"]
        joint_states = [m for m in _messages(shard_set / name) if m[0] == "/joint_states"]
        steps.append(len(joint_states))
    assert steps == [601, 600], "the shards share out the 1201 steps"
    assert custom_data(shard_set / "shard-0")["causal_arm.seed"] == str(SEED), "shard 0 keeps the run's seed"


def test_a_shard_is_the_plain_run_of_its_seed_and_share(shard_set, run_cli, tmp_path):
    seed = custom_data(shard_set / "shard-1")["causal_arm.seed"]
    r = run_cli("generate", "exp1", "--steps", "600", "--seed", seed, "--out", tmp_path / "plain")
    assert r.returncode == 0, r.stderr
    assert _messages(shard_set / "shard-1") == _messages(tmp_path / "plain")


def _train(run_cli, bag, out):
    r = run_cli("train", "--bag", bag, "--model", "fm", "--epochs", "2", "--folds", "2", "--fm-hidden", "16",
                "--out", out, "--no-cache", timeout=300)
    assert r.returncode == 0, r.stderr
    return r.stderr, json.loads((out / "metrics.json").read_text())


def test_train_takes_the_set_as_one_dataset_and_repeats_itself(shard_set, run_cli, tmp_path):
    log, first = _train(run_cli, shard_set, tmp_path / "a")
    assert "shard-0" in log and "shard-1" in log
    # 600 + 599 transitions: none crosses from one shard into the next.
    assert first["rows"] == 1199
    _, second = _train(run_cli, shard_set, tmp_path / "b")
    assert first["models"]["fm"]["figures"] == second["models"]["fm"]["figures"]


def test_a_set_missing_a_shard_is_refused_naming_it(shard_set, run_cli, tmp_path):
    broken = tmp_path / "broken"
    shutil.copytree(shard_set, broken)
    shutil.rmtree(broken / "shard-1")
    r = run_cli("train", "--bag", broken, "--model", "fm", "--epochs", "1", "--out", tmp_path / "m", "--no-cache")
    assert r.returncode != 0
    assert "shard-1" in r.stderr and "incomplete" in r.stderr, r.stderr


@pytest.mark.parametrize("args,message", [
    (["exp1", "--steps", "100", "--shards", "0"], "--shards must be at least 1, got 0"),
    (["exp1", "--steps", "100", "--shards", "-2"], "--shards must be at least 1, got -2"),
    (["exp2", "--episodes", "1", "--shards", "2"], "2 shards for 1 episode(s) of 500 steps leave a shard without work"),
    (["exp1", "--steps", "100", "--shards", "2", "--resume"], "--resume continues one bag"),
])
def test_bad_shard_counts_are_refused(run_cli, tmp_path, args, message):
    r = run_cli("generate", *args, "--out", tmp_path / "out")
    assert r.returncode != 0 and message in r.stderr, r.stderr
    assert not (tmp_path / "out").exists(), "nothing is written"


def test_bag_check_judges_every_shard(shard_set, run_cli, tmp_path):
    r = run_cli("bag", "check", shard_set)
    assert r.returncode == 0, r.stderr
    assert [report["sound"] for report in json.loads(r.stdout)] == [True, True]
    broken = tmp_path / "broken"
    shutil.copytree(shard_set, broken)
    for mcap in (broken / "shard-0").glob("*.mcap"):
        mcap.write_bytes(mcap.read_bytes()[:-300])  # cut short, as by a crash
    r = run_cli("bag", "check", broken)
    assert r.returncode != 0 and "1 of 2 shards failed" in r.stderr and "shard-0" in r.stderr, r.stderr


def test_launch_shards_run_graphs_side_by_side_into_the_same_set(shard_set, run_cli, tmp_path, private_netns):
    """`launch --shards 2`: two DDS graphs, shard i in domain ROS_DOMAIN_ID + i, record
    the shard set `generate --shards 2` writes for the same seed, message for message."""
    out = tmp_path / "launched"
    r = run_cli("launch", "exp1", "--steps", "1201", "--seed", SEED, "--shards", "2", "--out", out,
                env={"ROS_DOMAIN_ID": "80"}, timeout=300)
    assert r.returncode == 0, r.stderr[-3000:]
    assert "2 graphs" in r.stdout, r.stdout
    assert yaml.safe_load((out / "shard_set.yaml").read_text()) == \
        yaml.safe_load((shard_set / "shard_set.yaml").read_text())
    for name in ["shard-0", "shard-1"]:
        assert custom_data(out / name) == custom_data(shard_set / name)
        assert _messages(out / name) == _messages(shard_set / name), name


def test_launch_refuses_shards_past_the_last_domain(run_cli, tmp_path, private_netns):
    r = run_cli("launch", "exp1", "--steps", "100", "--shards", "3", "--out", tmp_path / "out",
                env={"ROS_DOMAIN_ID": "231"})
    assert r.returncode != 0 and "need domains up to 233" in r.stderr, r.stderr
    assert not (tmp_path / "out").exists()
