"""The architecture's rules, checked against cargo's own view of the workspace, so
docs/ARCHITECTURE.md stays true: its crate table matches `cargo metadata`, no library imports
a node crate, the trainer and explainer build no physics, the babbler no simulator, and the
async runtime is tokio alone."""

import json
import pathlib
import re
import subprocess

import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]
# Node binaries: one main.rs each around a library call.
NODE_BINARIES = ["sim", "babbler", "recorder", "reacher", "trainer", "explainer"]


def short(name: str) -> str:
    return name.removeprefix("causal_arm_")


@pytest.fixture(scope="module")
def workspace():
    """{crate: (path relative to the repo, {dependency kind: set of project crates})}."""
    out = subprocess.run(["cargo", "metadata", "--format-version", "1", "--no-deps", "--locked"],
                         cwd=REPO, capture_output=True, text=True, check=True).stdout
    packages = json.loads(out)["packages"]
    names = {p["name"] for p in packages}
    crates = {}
    for p in packages:
        path = str(pathlib.Path(p["manifest_path"]).parent.relative_to(REPO))
        deps = {"normal": set(), "dev": set(), "build": set()}
        for d in p["dependencies"]:
            if d["name"] in names:
                deps[d["kind"] or "normal"].add(d["name"])
        crates[p["name"]] = (path, deps)
    return crates


def documented_table():
    """Rows of the crate table in docs/ARCHITECTURE.md: {crate: (path, set of short deps)}."""
    text = (REPO / "docs" / "ARCHITECTURE.md").read_text()
    rows = {}
    for line in text.splitlines():
        m = re.match(r"\| `([^`]+)` \| `([^`]+)` \| .* \| ([^|]*) \|$", line)
        if m:
            deps = {d.strip() for d in m.group(3).split(",") if d.strip() not in ("", "—")}
            rows[m.group(1)] = (m.group(2), deps)
    return rows


def test_the_documented_crate_table_is_cargos(workspace):
    table = documented_table()
    assert set(table) == set(workspace), "crates missing from or extra in docs/ARCHITECTURE.md"
    for crate, (path, deps) in workspace.items():
        assert table[crate][0] == path, f"{crate}: documented at {table[crate][0]}, is at {path}"
        actual = {short(d) for d in deps["normal"]}
        assert table[crate][1] == actual, f"{crate}: documented deps {table[crate][1]}, cargo says {actual}"


def test_no_library_imports_a_node_crate(workspace):
    """`nodes/` holds node binaries only; nothing, not even the command line, imports one."""
    nodes = {c for c, (path, _) in workspace.items() if path.startswith("nodes/")}
    assert {f"causal_arm_{n}_node" for n in ("sim", "babbler", "recorder", "reacher")} | \
        {"causal_arm_trainer", "causal_arm_explainer"} == nodes
    for crate, (path, deps) in workspace.items():
        for kind, names in deps.items():
            assert not names & nodes, f"{crate} ({path}) has {kind} dependencies on nodes {names & nodes}"


def cargo_tree(package: str) -> str:
    return subprocess.run(["cargo", "tree", "--locked", "-e", "normal", "-p", package, "--prefix", "none"],
                          cwd=REPO, capture_output=True, text=True, check=True).stdout


@pytest.mark.parametrize("package", ["causal_arm_trainer", "causal_arm_explainer", "causal_arm_models",
                                     "causal_arm_explain"])
def test_the_learning_nodes_build_no_physics(package):
    assert "rapier3d" not in cargo_tree(package)


@pytest.mark.parametrize("package", ["causal_arm_models", "causal_arm_explain", "causal_arm_fuzz"])
def test_the_learning_libraries_build_no_dds(package):
    """The trainer and explainer nodes are thin mains around these: the CLI and the fuzz
    harness use them without linking rustdds, ros2-client or OpenSSL."""
    tree = cargo_tree(package)
    assert not {"rustdds", "ros2-client", "openssl"} & {line.split(" ")[0] for line in tree.splitlines()}


def test_the_node_crates_are_thin_mains():
    """Every crate under `nodes/` holds one binary, `src/main.rs`, and no library."""
    for node in NODE_BINARIES:
        src = REPO / "nodes" / node / "src"
        assert sorted(f.name for f in src.rglob("*.rs")) == ["main.rs"], f"nodes/{node}"
    assert sorted(p.name for p in (REPO / "nodes").iterdir() if p.is_dir()) == sorted(NODE_BINARIES)


def test_the_babbler_builds_no_simulator():
    tree = cargo_tree("causal_arm_babbler")
    assert "causal_arm_sim " not in tree and "rapier3d" not in tree


def test_tokio_is_the_only_async_runtime():
    lock = (REPO / "Cargo.lock").read_text()
    packages = set(re.findall(r'^name = "([^"]+)"', lock, re.M))
    assert "tokio" in packages
    assert not packages & {"smol", "async-std", "ctrlc"}, packages & {"smol", "async-std", "ctrlc"}


def test_one_module_style(workspace):
    """A module with submodules is `name/mod.rs`, never `name.rs` beside a `name/` folder
    (cargo's test helpers, `tests/common/mod.rs`, follow the same rule)."""
    mixed = []
    for path, _ in workspace.values():
        for folder in (REPO / path).rglob("*"):
            if folder.is_dir() and "target" not in folder.parts and (folder.parent / f"{folder.name}.rs").is_file():
                mixed.append(str((folder.parent / f"{folder.name}.rs").relative_to(REPO)))
    assert not mixed, f"name.rs beside name/ (use name/mod.rs): {mixed}"


def test_the_explain_pipeline_is_assembled_once():
    """`causal_arm_explain::run` is the one explain job: the CLI and the node call it, and
    neither assembles claims, scores or files of its own."""
    for front in ("crates/cli/src/explain_cmd.rs", "nodes/explainer/src/main.rs"):
        text = (REPO / front).read_text()
        assert "causal_arm_explain::run(" in text, front
        for assembled in ("shap_and_cai_claims", "score_claims", "calibrated_relevance", "std::fs::write",
                          "write_all("):
            assert assembled not in text, f"{front} assembles {assembled} itself"


def project_sources():
    """The project's own Rust sources outside tests (tests/ folders and tests.rs modules);
    generated code lives in OUT_DIR, not here, and the vendored forks under patches/."""
    for base in ("crates", "nodes", "msgs"):
        for path in sorted((REPO / base).rglob("*.rs")):
            if "tests" in path.relative_to(REPO).parts or path.name == "tests.rs":
                continue
            yield path


def test_no_source_file_over_600_lines_and_no_function_over_100():
    """Small pieces a newcomer can read: a file of at most 600 lines, a function of at most
    100 (from its `fn` line to the closing brace at the same indentation)."""
    fn = re.compile(r"^(\s*)(pub(\([a-z]+\))? )?(async )?(const )?(unsafe )?fn \w+")
    long_files, long_functions = [], []
    for path in project_sources():
        lines = path.read_text().splitlines()
        where = path.relative_to(REPO)
        if len(lines) > 600:
            long_files.append(f"{where}: {len(lines)} lines")
        for i, line in enumerate(lines):
            m = fn.match(line)
            if not m or line.rstrip().endswith(";"):
                continue
            end = next((j for j in range(i + 1, len(lines)) if lines[j] == m.group(1) + "}"), i)
            if end - i + 1 > 100:
                long_functions.append(f"{where}:{i + 1}: {end - i + 1} lines")
    assert not long_files and not long_functions, long_files + long_functions


@pytest.mark.parametrize("message,ok", [
    ("dataset: read each row's design\n\nThe detail.\n", True),
    ("a subject alone\n", True),
    ("# git's template\nfix the hang\n\nbody\n", True),
    ("x" * 73 + "\n", False),
    ("a subject\nno blank line\n", False),
    ("\n\nbody only\n", False),
])
def test_the_commit_msg_hook_keeps_subjects_short(tmp_path, message, ok):
    """The README's hook (.githooks/commit-msg): subjects of at most 72 characters, the
    detail in the body after a blank line."""
    path = tmp_path / "COMMIT_EDITMSG"
    path.write_text(message)
    r = subprocess.run([str(REPO / ".githooks" / "commit-msg"), str(path)], capture_output=True, text=True)
    assert (r.returncode == 0) == ok, r.stderr
    assert ok or r.stderr.startswith("commit-msg: ")
