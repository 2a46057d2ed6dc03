"""patches/rebuild.sh, which `tests/run_all.sh` runs to check that the vendored forks in
patches/ are exactly their pristine crates.io crates plus their patch series, must fail when
they are not: its self-test changes one byte and adds a file in a temporary copy of each
fork and applies a series twice, and each must be caught and named. Needs the pristine
crates in cargo's or the script's cache (the check step of `tests/run_all.sh` downloads them)
or crates.io."""

import subprocess


def test_rebuild_sh_catches_a_changed_byte_a_stray_file_and_a_diff_that_does_not_apply(repo_root, tmp_path):
    script = repo_root / "patches" / "rebuild.sh"
    r = subprocess.run(["bash", str(script), "--self-test"], cwd=tmp_path, capture_output=True, text=True,
                       timeout=60)
    assert r.returncode == 0, r.stdout + r.stderr
    forks = sorted(p.stem for p in (repo_root / "patches").glob("*.series"))
    assert forks, "no patches/*.series"
    lines = r.stdout.splitlines()
    assert len(lines) == len(forks), r.stdout
    for fork, line in zip(forks, lines):
        assert line.startswith(f"{fork} ") and f"patches/{fork}/src/lib.rs" in line, line
        assert "self-test passed" in line, line
