"""Full disks: every writer names the cause, keeps what it wrote readable, and never
destroys a previous result. Each case runs in a private mount namespace on a small tmpfs
(`unshare -m`), so the host's disks are never filled."""

import json
import shutil
import subprocess

import pytest


def in_small_fs(script: str, size: str, tmp_path, causal_arm_bin, timeout=300):
    """Runs a shell `script` with $D a fresh tmpfs of `size` and $CA our binary; returns the
    CompletedProcess. Output files are copied out to tmp_path/out by the script itself."""
    if shutil.which("unshare") is None:
        pytest.fail("unshare (util-linux) is needed for the full-disk tests")
    out = tmp_path / "out"
    out.mkdir()
    full = f"set -u; D={tmp_path}/fs; mkdir -p $D; mount -t tmpfs -o size={size} tmpfs $D; " \
           f"CA={causal_arm_bin}; OUT={out}; {script}"
    return subprocess.run(["unshare", "-m", "sh", "-c", full], capture_output=True, text=True,
                          timeout=timeout)


def test_generate_on_a_full_disk_names_the_cause_and_leaves_a_readable_bag(causal_arm_bin, tmp_path):
    r = in_small_fs(
        "$CA generate exp1 --steps 20000 --seed 4 --out $D/bag > $OUT/gen.out 2> $OUT/gen.err; "
        "echo $? > $OUT/gen.rc; "
        "$CA bag info $D/bag > $OUT/info.json 2> $OUT/info.err; echo $? > $OUT/info.rc; "
        "$CA train --bag $D/bag --model fm --epochs 1 --folds 2 --max-folds 1 --fm-hidden 8 "
        "--cache $D/cache --out $OUT/models > /dev/null 2> $OUT/train.err; echo $? > $OUT/train.rc",
        "2M", tmp_path, causal_arm_bin)
    assert r.returncode == 0, r.stderr
    out = tmp_path / "out"
    gen_err = (out / "gen.err").read_text()
    assert (out / "gen.rc").read_text().strip() != "0", "generate succeeded on a 2 MB disk"
    assert "No space left on device" in gen_err, gen_err[-600:]
    # What was written stays readable: the index was kept current, so standard readers and
    # ours open the bag, cut short at its last complete chunk, and train warns about it.
    assert (out / "info.rc").read_text().strip() == "0", (out / "info.err").read_text()
    info = json.loads((out / "info.json").read_text())
    assert info["message_count"] > 1000 and not info["complete"], info
    assert "incomplete" in (out / "info.err").read_text()
    train_err = (out / "train.err").read_text()
    assert (out / "train.rc").read_text().strip() == "0", train_err[-600:]
    assert "incomplete" in train_err, train_err[-600:]


def test_a_retrain_on_a_full_disk_keeps_the_previous_model(causal_arm_bin, tmp_path):
    train = ("$CA train --bag $OUT/bag --model fm --epochs 1 --folds 2 --max-folds 1 --fm-hidden {h} "
             "--cache $OUT/cache --out $D/models")
    r = subprocess.run([str(causal_arm_bin), "generate", "exp1", "--steps", "300", "--seed", "4",
                        "--out", tmp_path / "out0" / "bag"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    r = in_small_fs(
        f"cp -r {tmp_path}/out0/bag $OUT/bag; " + train.format(h=8) + " > /dev/null 2> $OUT/t1.err; "
        "echo $? > $OUT/t1.rc; sha256sum $D/models/fm.safetensors > $OUT/before; "
        "cat /dev/zero > $D/filler 2>/dev/null; "
        + train.format(h=16) + " > /dev/null 2> $OUT/t2.err; echo $? > $OUT/t2.rc; "
        "sha256sum $D/models/fm.safetensors > $OUT/after; ls -a $D/models > $OUT/ls",
        "64M", tmp_path, causal_arm_bin)
    assert r.returncode == 0, r.stderr
    out = tmp_path / "out"
    assert (out / "t1.rc").read_text().strip() == "0", (out / "t1.err").read_text()[-600:]
    t2 = (out / "t2.err").read_text()
    assert (out / "t2.rc").read_text().strip() != "0", "a retrain succeeded on a full disk"
    assert "No space left on device" in t2, t2[-600:]
    assert (out / "before").read_text().split()[0] == (out / "after").read_text().split()[0]
    assert ".partial" not in (out / "ls").read_text()
