"""A hostile corpus of damaged bags: truncations, byte flips in every kind of record,
chunk headers with wrong sizes, broken or missing metadata.yaml, junk files. Each is fed
to `bag info`, `train`, `explain`, `rollout` and `play`; none may hang (30 s), panic or
abort, and none may exit 0 on damage. Only a crash tail (a bare .mcap cut short, as a
killed writer leaves it) may be read, with a warning. Every error names the file and the
place. `bag check` refuses every damaged bag, and `bag recover` restores every complete
chunk."""

import json
import os
import pathlib
import shutil
import struct
import subprocess

import pytest

from conftest import bag_and_forward_model, in_private_netns

CHUNK, MESSAGE_INDEX, FOOTER, METADATA, HEADER, DATA_END = 0x06, 0x07, 0x02, 0x0C, 0x01, 0x0F


def records(data: bytes):
    """(offset, opcode, length) of every top-level record of a sound MCAP file."""
    out, pos = [], 8
    while pos + 9 <= len(data) - 8:
        op, length = data[pos], struct.unpack_from("<Q", data, pos + 1)[0]
        out.append((pos, op, length))
        if op == FOOTER:
            break
        pos += 9 + length
    return out


def flipped(data: bytes, at: int, mask: int = 0xFF) -> bytes:
    b = bytearray(data)
    b[at] ^= mask
    return bytes(b)


def with_uncompressed_size(data: bytes, chunk_at: int, change) -> bytes:
    """The chunk header's uncompressed_size field (after two u64 times) rewritten."""
    field = chunk_at + 9 + 16
    (size,) = struct.unpack_from("<Q", data, field)
    b = bytearray(data)
    struct.pack_into("<Q", b, field, change(size) & (2**64 - 1))
    return bytes(b)


def mcap_corpus(data: bytes):
    """name → damaged bytes of the MCAP file (all of them damage, none a crash tail)."""
    recs = records(data)
    chunks = [r for r in recs if r[1] == CHUNK]
    assert len(chunks) >= 3, f"the corpus needs a bag of several chunks, got {len(chunks)}"
    mid = chunks[len(chunks) // 2]
    index = next(r for r in recs if r[1] == MESSAGE_INDEX)
    meta = next(r for r in recs if r[1] == METADATA)
    footer = next(r for r in recs if r[1] == FOOTER)
    data_end = next(r for r in recs if r[1] == DATA_END)
    corpus = {
        "start magic": flipped(data, 1),
        "header record": flipped(data, 8 + 9 + 5, 0x01),
        "metadata record": flipped(data, meta[0] + meta[2], 0x01),
        "first chunk data": flipped(data, chunks[0][0] + 9 + 60),
        "mid chunk data": flipped(data, mid[0] + mid[2] // 2, 0x01),
        "mid chunk crc": flipped(data, mid[0] + 9 + 24),
        "mid chunk start time": flipped(data, mid[0] + 9 + 2, 0x01),
        "mid chunk opcode": flipped(data, mid[0], 0x80),
        "mid chunk length": flipped(data, mid[0] + 4, 0x10),
        "mid chunk compression name": flipped(data, mid[0] + 9 + 32 + 1),
        "last chunk data": flipped(data, chunks[-1][0] + chunks[-1][2], 0x01),
        "message index": flipped(data, index[0] + 9 + 12, 0x01),
        "data end crc": flipped(data, data_end[0] + 9),
        "summary": flipped(data, data_end[0] + 13 + 20),
        "footer": flipped(data, footer[0] + 9 + 3),
        "end magic": flipped(data, len(data) - 2),
        "zeroed middle": data[: len(data) // 2] + bytes(64) + data[len(data) // 2 + 64:],
        "duplicated chunk": data[: mid[0]] + data[mid[0]: mid[0] + 9 + mid[2]] + data[mid[0]:],
        "removed chunk": data[: mid[0]] + data[mid[0] + 9 + mid[2]:],
    }
    for name, change in [("+1", lambda s: s + 1), ("-1", lambda s: s - 1), ("+32", lambda s: s + 32),
                         ("-32", lambda s: s - 32), ("x2", lambda s: s * 2), ("huge", lambda s: 1 << 62)]:
        corpus[f"uncompressed_size {name}"] = with_uncompressed_size(data, mid[0], change)
    return corpus


@pytest.fixture(scope="module")
def sound(run_cli, tmp_path_factory):
    """A sound exp1 bag of several chunks and a forward model trained on it."""
    d = tmp_path_factory.mktemp("corrupt")
    bag_and_forward_model(run_cli, d, ["exp1", "--profile", "quick", "--steps", "4000", "--seed", "2"],
                          ["--epochs", "2", "--folds", "2", "--max-folds", "1", "--fm-hidden", "16"])
    return d


def damaged_bags(sound: pathlib.Path, root: pathlib.Path):
    """(name, path, is_crash_tail) of every corpus entry, written under root."""
    src = sound / "bag"
    mcap_name = next(p.name for p in src.iterdir() if p.suffix == ".mcap")
    data = (src / mcap_name).read_bytes()
    meta = (src / "metadata.yaml").read_text()
    out = []

    def bag_dir(name, mcap_bytes=data, metadata=meta):
        d = root / name.replace(" ", "_")
        d.mkdir()
        (d / mcap_name).write_bytes(mcap_bytes)
        if metadata is not None:
            (d / "metadata.yaml").write_text(metadata)
        return d

    for name, damaged in mcap_corpus(data).items():
        out.append((name, bag_dir(name, damaged), False))
    for frac in (0.1, 0.5, 0.9):
        cut = data[: int(len(data) * frac)]
        out.append((f"cut {frac} bag", bag_dir(f"cut {frac} bag", cut), False))
        bare = root / f"cut_{frac}.mcap"
        bare.write_bytes(cut)
        out.append((f"cut {frac} bare", bare, True))
    out.append(("metadata missing", bag_dir("metadata missing", metadata=None), False))
    out.append(("metadata junk", bag_dir("metadata junk", metadata="{{ not yaml"), False))
    out.append(("metadata empty", bag_dir("metadata empty", metadata=""), False))
    more = meta.replace("message_count: ", "message_count: 1", 1)
    out.append(("metadata counts more", bag_dir("metadata counts more", metadata=more), False))
    other = meta.replace(mcap_name, "other_0.mcap")
    out.append(("metadata names another file", bag_dir("metadata names another file", metadata=other), False))
    for name, content in [("empty", b""), ("magic only", data[:8]), ("text", b"hello, not a bag\n"),
                          ("random", os.urandom(5000)), ("header only", data[: records(data)[1][0]])]:
        f = root / f"{name.replace(' ', '_')}.mcap"
        f.write_bytes(content)
        out.append((name, f, False))
    d = root / "mcap_is_a_dir"
    (d / "x_0.mcap").mkdir(parents=True)
    out.append(("mcap is a directory", d, False))
    return out


def commands(sound, bag, out):
    model = sound / "models"
    cache = ["--cache", out / "cache"]
    return {
        "info": ["bag", "info", bag],
        "train": ["train", "--bag", bag, "--model", "fm", "--epochs", "1", "--folds", "2", "--max-folds", "1",
                  "--fm-hidden", "8", "--out", out / "m", *cache],
        "explain": ["explain", "--model", model, "--bag", bag, "--method", "deep", "--samples", "20",
                    "--background", "20", "--out", out / "x", *cache],
        "rollout": ["rollout", "--model", model, "--bag", bag, "--trajectories", "5", "--steps", "3",
                    "--out", out / "r", *cache],
        "play": ["play", bag, "--rate", "0", "--delay", "0"],
    }


def test_the_corpus_is_refused_by_name_and_never_hangs(run_cli, sound, tmp_path):
    if not in_private_netns():
        pytest.fail("play starts DDS participants: run inside tests/netns-run")
    corpus = damaged_bags(sound, tmp_path)
    assert len(corpus) >= 40
    defects = []
    for name, bag, crash_tail in corpus:
        for command, args in commands(sound, bag, tmp_path / "out" / name.replace(" ", "_")).items():
            r = run_cli(*args, timeout=30)
            if "[test harness: killed after" in r.stderr:
                defects.append(f"{name} / {command}: hang (30 s)")
                continue
            err = r.stderr
            if r.returncode < 0 or "panicked" in err:
                defects.append(f"{name} / {command}: crash {r.returncode}: {err[-300:]}")
            elif r.returncode == 0 and not crash_tail:
                defects.append(f"{name} / {command}: exit 0 on damaged input")
            elif r.returncode == 0 and "incomplete" not in err:
                defects.append(f"{name} / {command}: read a cut-short bag without a warning")
            elif r.returncode != 0 and not names_file_and_place(err, bag):
                defects.append(f"{name} / {command}: error does not name file and place: {err[-300:]}")
    assert not defects, f"{len(defects)} defective runs:\n" + "\n".join(defects)


def names_file_and_place(err: str, bag: pathlib.Path) -> bool:
    """The error names the bag (its directory or file) and where: a byte offset, a chunk,
    metadata.yaml, or the file as a whole (empty, not MCAP, not a file, cut short)."""
    names_file = str(bag) in err
    places = ("byte ", "metadata.yaml", "empty", "not an MCAP file", "not a regular file",
              "no readable messages", "cut short", "complete steps", "transitions")
    return names_file and any(p in err for p in places)


def test_bag_check_refuses_damage_and_recover_restores_every_complete_chunk(run_cli, sound, tmp_path):
    r = run_cli("bag", "check", sound / "bag")
    assert r.returncode == 0, r.stderr
    report = json.loads(r.stdout)
    assert report["sound"] and report["steps"]["transitions"] > 3000
    full = report["readable_messages"]

    src = sound / "bag"
    data = next(p for p in src.iterdir() if p.suffix == ".mcap").read_bytes()
    for name, damaged in mcap_corpus(data).items():
        f = tmp_path / f"{name.replace(' ', '_')}.mcap"
        f.write_bytes(damaged)
        r = run_cli("bag", "check", f)
        assert r.returncode == 1, f"{name}: bag check passed a damaged file"
        report = json.loads(r.stdout)
        assert report["damage"] and not report["sound"], name

    # One chunk damaged in the middle: recover keeps every other chunk and says what was lost.
    mid = [r for r in records(data) if r[1] == CHUNK]
    chunk = mid[len(mid) // 2]
    f = tmp_path / "one_bad_chunk.mcap"
    f.write_bytes(flipped(data, chunk[0] + chunk[2] // 2, 0x01))
    r = run_cli("bag", "recover", f, "--out", tmp_path / "recovered")
    assert r.returncode == 0, r.stderr
    report = json.loads(r.stdout)
    lost = report["messages_in_damaged_chunks"]
    assert 0 < lost < full / 3 and report["recovered_messages"] + lost == full, report
    r = run_cli("bag", "check", tmp_path / "recovered")
    assert r.returncode != 0 or json.loads(r.stdout)["sound"]  # the hole in the steps is named
    from rosbags.highlevel import AnyReader
    with AnyReader([tmp_path / "recovered"]) as reader:
        assert sum(1 for _ in reader.messages()) == report["recovered_messages"]

    # A crash tail: recover finishes it with every complete chunk.
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: int(len(data) * 0.6)])
    r = run_cli("bag", "check", cut)
    assert r.returncode == 1 and json.loads(r.stdout)["truncation"]
    r = run_cli("bag", "recover", cut, "--out", tmp_path / "finished")
    assert r.returncode == 0, r.stderr
    r = run_cli("bag", "info", tmp_path / "finished")
    assert r.returncode == 0 and json.loads(r.stdout)["complete"], r.stderr
    shutil.rmtree(tmp_path / "finished")
