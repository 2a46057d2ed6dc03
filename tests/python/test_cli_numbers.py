"""A negative number given to a numeric option is a value, not a flag: the command refuses it
by name with the rule it breaks (exit 1), instead of clap's "unexpected argument '-1'"."""

import subprocess

import pytest


@pytest.fixture(scope="module")
def tiny_bag(run_cli, tmp_path_factory):
    bag = tmp_path_factory.mktemp("neg") / "bag"
    assert run_cli("generate", "exp1", "--steps", "20", "--seed", "1", "--out", bag).returncode == 0
    return bag


@pytest.mark.parametrize("args,message", [
    (["generate", "exp1", "--steps", "10", "--sigma", "-1"], "sigma must be a finite non-negative number"),
    (["generate", "exp1", "--steps", "10", "--velocity-scale", "-1"], "--velocity-scale must be a positive number, got -1"),
    (["generate", "exp1", "--steps", "10", "--velocity-scale", "1e12"], "--velocity-scale must lie in [0.01, 1000]"),
    (["train", "--lr", "-1", "--bag", "BAG"], "learning rate must be a positive number, got -1"),
    (["train", "--max-folds", "0", "--bag", "BAG"], "--max-folds must be at least 1"),
    (["play", "BAG", "--rate", "-1"], "--rate must be a non-negative number, got -1"),
    (["play", "BAG", "--delay", "-0.5"], "--delay must be non-negative"),
    (["intervene", "exp1", "--bag", "BAG", "--states", "5", "--tolerance", "-1"], "--tolerance must be a non-negative number, got -1"),
    (["intervene", "exp1", "--bag", "BAG", "--states", "5", "--min-fraction", "-1"], "--min-fraction must lie in [0, 1], got -1"),
    (["topic", "pub", "/x", "--type", "std_msgs/msg/String", "--json", "{}", "--rate", "-1"], "--rate must be a positive number of Hz, got -1"),
    (["service", "call", "/x", "--type", "causal_arm_msgs/srv/GetModelInfo", "--json", "{}", "--timeout", "-2"], "--timeout must be a positive number of seconds, got -2"),
])
def test_negative_numbers_are_values_refused_by_name(run_cli, tiny_bag, tmp_path, private_netns, args, message):
    args = [tiny_bag if a == "BAG" else a for a in args]
    if args[0] in ("generate", "train", "intervene"):
        args += ["--out", tmp_path / "out"]
    r = run_cli(*args)
    assert r.returncode == 1, r.stderr
    assert message in r.stderr, r.stderr
    assert "unexpected argument" not in r.stderr


def test_a_closed_stdout_ends_the_cli_quietly(causal_arm_bin, tiny_bag):
    """`causal-arm … | head` must end like any Unix tool when the reader goes away: by
    SIGPIPE, never by a Rust panic on EPIPE."""
    r = subprocess.run(f"'{causal_arm_bin}' bag check '{tiny_bag}' | true", shell=True,
                       capture_output=True, text=True, timeout=60)
    assert "panicked" not in r.stderr and "Broken pipe" not in r.stderr, r.stderr
