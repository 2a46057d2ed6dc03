"""A writer killed by SIGKILL leaves a bag that standard readers open: metadata.yaml is
written when the bag opens and kept current as chunks land (as rosbag2 does), the MCAP
library's stream reader reads every message the index counts, our reader reads every
complete chunk with a warning, and `bag recover` finishes it into a bag rosbags reads.
(rosbags itself refuses any MCAP file without its closing magic.)"""

import json
import signal
import subprocess
import time

import yaml


def test_sigkill_of_generate_leaves_a_bag_rosbags_opens(causal_arm_bin, run_cli, tmp_path):
    bag = tmp_path / "killed"
    proc = subprocess.Popen([str(causal_arm_bin), "generate", "exp1", "--steps", "2000000", "--seed", "5",
                             "--out", bag], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        meta = bag / "metadata.yaml"
        if meta.exists() and yaml.safe_load(meta.read_text())["rosbag2_bagfile_information"]["message_count"] > 20000:
            break
        time.sleep(0.05)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    counted = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]["message_count"]
    assert counted > 20000, "the index was not kept current while writing"

    from mcap.exceptions import EndOfFile, RecordLengthLimitExceeded
    from mcap.records import Message
    from mcap.stream_reader import StreamReader
    read = 0
    with open(next(bag.glob("*.mcap")), "rb") as f:
        try:
            for record in StreamReader(f).records:
                read += isinstance(record, Message)
        except (EndOfFile, RecordLengthLimitExceeded):  # the cut-off chunk at the end
            pass
    assert read >= counted

    r = run_cli("bag", "info", bag)
    assert r.returncode == 0, r.stderr
    info = json.loads(r.stdout)
    assert not info["complete"] and info["message_count"] >= counted
    assert "incomplete" in r.stderr
    r = run_cli("bag", "recover", bag, "--out", tmp_path / "finished")
    assert r.returncode == 0, r.stderr
    report = json.loads(r.stdout)
    # The run was killed mid-step: that half step is dropped, nothing else.
    assert 0 <= report["dropped_partial_last_stamp"] < 8
    assert report["recovered_messages"] + report["dropped_partial_last_stamp"] == info["message_count"]
    from rosbags.highlevel import AnyReader
    with AnyReader([tmp_path / "finished"]) as reader:
        assert sum(1 for _ in reader.messages()) == report["recovered_messages"]
    r = run_cli("bag", "check", tmp_path / "finished")
    assert r.returncode == 0, r.stdout[-800:] + r.stderr[-800:]
