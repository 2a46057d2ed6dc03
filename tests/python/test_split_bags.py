"""Bags split like rosbag2's (`--max-bag-size`, `--max-bag-duration`; issue 40, item 2):
rosbag2's file names and metadata.yaml, every closed file finished and readable alone by
rosbags and mcap-ros2-support, the files read as one bag by train, intervene and `bag`,
and a killed run's closed splits intact and resumed into the bag of an uninterrupted run."""

import json
import os
import pathlib
import signal
import subprocess
import time

import pytest
import yaml
from mcap_ros2.reader import read_ros2_messages
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import Reader

from test_datagen import assert_same_bag

RUN = ["exp2", "--episodes", "6", "--seed", "2"]


def _messages(path: pathlib.Path) -> list:
    """Every message of a bag directory or a lone MCAP file as (topic, log time, CDR), by rosbags."""
    with Reader(path) as reader:
        return [(c.topic, t, bytes(raw)) for c, t, raw in reader.messages()]


def _info(bag: pathlib.Path) -> dict:
    return yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]


@pytest.fixture(scope="module")
def bags(run_cli, tmp_path_factory):
    """The same run (125 s of its clock) unsplit, split every 30 s, and split every 400 kB."""
    d = tmp_path_factory.mktemp("split")
    for name, split in [("whole", []), ("timed", ["--max-bag-duration", "30"]),
                        ("sized", ["--max-bag-size", "400000"])]:
        r = run_cli("generate", *RUN, *split, "--out", d / name)
        assert r.returncode == 0, r.stderr
    return d


def test_split_files_are_named_and_listed_as_rosbag2_does(bags):
    bag = bags / "timed"
    info = _info(bag)
    names = info["relative_file_paths"]
    assert len(names) == 5 and names == [f"timed_{i}.mcap" for i in range(len(names))], names
    assert sorted(p.name for p in bag.glob("*.mcap")) == sorted(names)
    assert [f["path"] for f in info["files"]] == names
    assert sum(f["message_count"] for f in info["files"]) == info["message_count"]
    # Each file spans at most 30 s of the run's clock, and starts where the last ended.
    for f in info["files"]:
        assert f["duration"]["nanoseconds"] <= 30 * 10**9, f
    starts = [f["starting_time"]["nanoseconds_since_epoch"] for f in info["files"]]
    assert starts == sorted(starts)


@pytest.mark.parametrize("name", ["timed", "sized"])
def test_a_split_bag_reads_as_the_unsplit_one_and_each_file_opens_alone(bags, name):
    bag, whole = bags / name, bags / "whole"
    assert _messages(bag) == _messages(whole), "rosbags reads the split bag as the whole one"
    alone = []
    for f in _info(bag)["files"]:
        path = bag / f["path"]
        messages = _messages(path)
        assert len(messages) == f["message_count"], path
        assert sum(1 for _ in read_ros2_messages(str(path))) == f["message_count"], path
        alone += messages
    assert alone == _messages(whole)
    if name == "sized":
        sizes = [(bag / f).stat().st_size for f in _info(bag)["relative_file_paths"]]
        # A file closes at the first chunk boundary past the limit (chunks are ~0.1-0.2 MB).
        assert len(sizes) >= 3 and all(400_000 <= s < 800_000 for s in sizes[:-1]), sizes


def test_bag_info_check_and_recover_take_the_files_as_one(bags, run_cli, tmp_path):
    bag = bags / "timed"
    info = json.loads(run_cli("bag", "info", bag).stdout)
    whole = json.loads(run_cli("bag", "info", bags / "whole").stdout)
    assert info["message_count"] == whole["message_count"] and info["topics"] == whole["topics"]
    assert [pathlib.Path(f["path"]).name for f in info["files"]] == _info(bag)["relative_file_paths"]
    r = run_cli("bag", "check", bag)
    assert r.returncode == 0, r.stdout[-2000:]
    report = json.loads(r.stdout)
    assert report["sound"] and report["steps"] == json.loads(run_cli("bag", "check", bags / "whole").stdout)["steps"]
    r = run_cli("bag", "recover", bag, "--out", tmp_path / "one")
    assert r.returncode == 0, r.stderr
    assert _messages(tmp_path / "one") == _messages(bags / "whole")
    r = run_cli("bag", "recover", bags / "whole", "--out", tmp_path / "resplit", "--max-bag-duration", "30")
    assert r.returncode == 0, r.stderr
    assert _info(tmp_path / "resplit")["relative_file_paths"] == [f"resplit_{i}.mcap" for i in range(5)]


def test_train_and_intervene_give_the_same_figures_on_split_and_unsplit_bags(bags, run_cli):
    figures = {}
    for name in ["whole", "timed"]:
        out = bags / f"models-{name}"
        r = run_cli("train", "--bag", bags / name, "--cache", bags / f"cache-{name}", "--model", "fm",
                    "--epochs", "2", "--folds", "2", "--fm-hidden", "16", "--out", out, timeout=600)
        assert r.returncode == 0, r.stderr[-2000:]
        fm = json.loads((out / "metrics.json").read_text())["models"]["fm"]
        truth = bags / f"truth-{name}"
        r = run_cli("intervene", "exp2", "--bag", bags / name, "--states", "40", "--out", truth, timeout=600)
        assert r.returncode == 0, r.stderr[-2000:]
        figures[name] = ([(f["key"], f["folds"]) for f in fm["figures"]], (truth / "truth.csv").read_text())
    assert figures["timed"] == figures["whole"]


def test_a_missing_split_is_refused_naming_it(bags, run_cli, tmp_path):
    holed = tmp_path / "timed"
    holed.mkdir()
    for f in (bags / "timed").iterdir():
        if f.name != "timed_2.mcap":
            (holed / f.name).write_bytes(f.read_bytes())
    r = run_cli("train", "--bag", holed, "--model", "fm", "--epochs", "1", "--out", tmp_path / "m")
    assert r.returncode != 0 and "timed_2.mcap" in r.stderr and "missing" in r.stderr, r.stderr[-2000:]


def test_a_killed_split_launch_keeps_its_closed_splits_and_resumes_into_the_uninterrupted_bag(
        causal_arm_bin, run_cli, tmp_path, private_netns):
    """SIGKILL of the recorder mid-run: every closed split is a finished bag file rosbags and
    mcap-ros2-support open alone; `launch --resume` then finishes the run into the bag, file
    for file, of `generate` with the same split."""
    run = ["exp2", "--episodes", "16", "--seed", "3", "--max-bag-duration", "20"]
    env = {**os.environ, "ROS_DOMAIN_ID": "23", "RUST_LOG": "warn"}
    out = tmp_path / "killed"
    proc = subprocess.Popen([str(causal_arm_bin), "launch", *run, "--out", str(out)], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    def listed() -> int:
        # The bag's own record: a split's file exists a moment before metadata.yaml lists it
        # (a crash in between leaves an unlisted file without messages, which readers skip).
        try:
            return len(_info(out)["relative_file_paths"])
        except (OSError, TypeError, KeyError):
            return 0

    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and listed() < 4:
        time.sleep(0.05)
    assert proc.poll() is None, "the run ended before the kill"
    children = [int(c) for c in pathlib.Path(f"/proc/{proc.pid}/task/{proc.pid}/children").read_text().split()]
    recorder = next(c for c in children
                    if pathlib.Path(f"/proc/{c}/comm").read_text().strip() in "causal_arm_recorder")
    os.kill(recorder, signal.SIGKILL)
    try:
        proc.communicate(timeout=30)
    finally:
        proc.kill()
    names = _info(out)["relative_file_paths"]
    assert len(names) >= 4 and names == sorted(names, key=lambda n: int(n[:-5].rsplit("_", 1)[1]))
    for name in names[:-1]:
        assert _messages(out / name), f"closed split {name} opens alone in rosbags"
        assert sum(1 for _ in read_ros2_messages(str(out / name))) > 0, name
    files = json.loads(run_cli("bag", "info", out).stdout)["files"]
    assert all(f["finished"] for f in files[:-1]) and not files[-1]["finished"], files
    r = run_cli("launch", *run, "--out", out, "--resume", env=env, timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    local = tmp_path / "local"
    assert run_cli("generate", *run, "--out", local).returncode == 0
    assert_same_bag(out, local, "differs from the uninterrupted run")
    resumed, uninterrupted = _info(out)["relative_file_paths"], _info(local)["relative_file_paths"]
    assert [n.replace("killed", "local") for n in resumed] == uninterrupted
    for a, b in zip(resumed, uninterrupted):
        assert _messages(out / a) == _messages(local / b), f"{a} holds other messages than {b}"
