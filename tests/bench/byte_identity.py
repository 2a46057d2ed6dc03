"""Bags and model files of two builds, compared byte for byte for the same seeds.

    python tests/bench/byte_identity.py OLD/causal-arm NEW/causal-arm [WORKDIR]

Runs `generate` (exp1, exp2, exp2 in 2 shards) and `train` (every model of each
experiment, quick profile, one fold) with each binary, then prints, per file, whether the
two builds wrote the same bytes; where a bag differs, whether its messages (topic, times,
sequence, payload) are the same and which records differ. Each build's bag is also written
twice, to tell a change between builds from a build that does not reproduce itself.
metrics.json is compared without its wall times. No DDS: run `launch`'s equality with
`generate` in tests/python/test_datagen.py."""

import json
import pathlib
import subprocess
import sys
import tempfile

from mcap.reader import make_reader
from mcap.stream_reader import StreamReader

RUNS = [("e1", ["exp1", "--steps", "3000", "--seed", "5"]),
        ("e2", ["exp2", "--episodes", "4", "--seed", "6"]),
        ("e2s", ["exp2", "--episodes", "4", "--seed", "6", "--shards", "2"])]


def run(binary, *args, env=None):
    r = subprocess.run([str(binary), *map(str, args)], capture_output=True, text=True, env=env)
    if r.returncode:
        sys.exit(f"{binary} {' '.join(map(str, args))} failed:\n{r.stderr[-2000:]}")


def messages(path):
    with open(path, "rb") as f:
        return [(c.topic, m.log_time, m.publish_time, m.sequence, bytes(m.data))
                for _, c, m in make_reader(f).iter_messages()]


def differing_record(a, b):
    with open(a, "rb") as fa, open(b, "rb") as fb:
        for i, (x, y) in enumerate(zip(StreamReader(fa, emit_chunks=True).records,
                                       StreamReader(fb, emit_chunks=True).records)):
            if x != y:
                return f"record {i}: {type(x).__name__} {getattr(x, 'id', '')} vs {type(y).__name__} {getattr(y, 'id', '')}"
    return "same records"


def without_wall_times(value):
    if isinstance(value, dict):
        return {k: without_wall_times(v) for k, v in value.items() if k != "wall_s"}
    if isinstance(value, list):
        return [without_wall_times(v) for v in value]
    return value


def main():
    old, new = map(pathlib.Path, sys.argv[1:3])
    work = pathlib.Path(sys.argv[3]) if len(sys.argv) > 3 else pathlib.Path(tempfile.mkdtemp())
    builds = (("old", old), ("new", new))
    for tag, binary in builds:
        for name, args in RUNS:
            for copy in (tag, f"{tag}-again"):
                run(binary, "generate", *args, "--out", work / copy / name)
    for tag, binary in builds:
        for name in ("e1", "e2"):
            env = {"CAUSAL_ARM_CACHE": str(work / tag / "cache"), "PATH": "/usr/bin:/bin"}
            # Both builds train on the same bag (the new build's), so the models compare alone.
            run(binary, "train", "--bag", work / "new" / name, "--model", "all", "--profile", "quick",
                "--max-folds", "1", "--out", work / tag / f"models-{name}", env=env)
    print(f"{'file':<44} {'old == new':<11} {'old reproduces':<15} {'new reproduces':<15} detail")
    for path in sorted(p for p in (work / "new").rglob("*") if p.is_file() and "cache" not in p.parts):
        rel = path.relative_to(work / "new")
        other = work / "old" / rel
        same = other.read_bytes() == path.read_bytes()
        detail = ""
        if rel.name == "metrics.json":
            same_but_time = without_wall_times(json.loads(other.read_text())) == \
                without_wall_times(json.loads(path.read_text()))
            detail = f"without wall times: {'same' if same_but_time else 'DIFFERENT'}"
        repro = {}
        for tag in ("old", "new"):
            again = work / f"{tag}-again" / rel
            repro[tag] = "-" if not again.exists() else \
                "yes" if again.read_bytes() == (work / tag / rel).read_bytes() else "NO"
        if rel.suffix == ".mcap" and not same:
            detail = (f"messages {'same' if messages(other) == messages(path) else 'DIFFERENT'}; "
                      f"first differing {differing_record(other, path)}")
        print(f"{str(rel):<44} {'yes' if same else 'NO':<11} {repro['old']:<15} {repro['new']:<15} {detail}")


if __name__ == "__main__":
    main()
