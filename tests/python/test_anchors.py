"""Tests of tests/bench/causal_anchors.py (the standard causal-discovery anchors) on
hand-built exp1-layout datasets whose true edges are known.

Run: target/anchorvenv/bin/python -m pytest -q tests/python/test_anchors.py
(venv: python3 -m venv target/anchorvenv; target/anchorvenv/bin/pip install -r
tests/bench/requirements-anchors.txt, which also installs next to tests/python's pins).
The test venv (tests/python/requirements.txt) installs tigramite and causal-learn for the
pcmci and pc checks; the rest needs numpy, scipy, scikit-learn and safetensors.
"""

from __future__ import annotations

import importlib.util
import json
import pathlib
import subprocess
import sys

import numpy as np
import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]
TOOL = REPO / "tests" / "bench" / "causal_anchors.py"


def _load_tool():
    spec = importlib.util.spec_from_file_location("causal_anchors", TOOL)
    module = importlib.util.module_from_spec(spec)
    sys.modules["causal_anchors"] = module  # dataclasses look their module up here
    spec.loader.exec_module(module)
    return module


anchors = _load_tool()

ACTIONS = [f"a{i}" for i in range(7)]
STATES = [f"theta{i}" for i in range(7)] + ["ef_x", "ef_y", "ef_z"]
# The only true edges of the hand-built data: a0 -> theta0 (linear), a1 -> ef_x (only
# through a1 * theta3, zero on average).
TRUE_EDGES = {("a0", "theta0"), ("a1", "ef_x")}


def make_transitions(rows: int = 5000, seed: int = 0, episode_len: int = 50,
                     noise: float = 0.01) -> dict[str, np.ndarray]:
    """exp1-layout tensors: episodes of `episode_len` steps. Δtheta0 = a0 + noise,
    Δef_x = a1 * theta3 + noise, theta6 never changes, every other feature mean-reverts
    (Δs = -0.2 s + noise, so theta3 stays symmetric around 0) whatever the actions."""
    rng = np.random.default_rng(seed)
    actions = rng.uniform(-1, 1, size=(rows, 7))
    states, next_states = np.zeros((rows, 10)), np.zeros((rows, 10))
    s = rng.normal(size=10)
    for t in range(rows):
        if t % episode_len == 0:
            s = rng.normal(size=10)
        d = -0.2 * s + noise * rng.normal(size=10)
        d[0] = actions[t, 0] + noise * rng.normal()
        d[7] = actions[t, 1] * s[3] + noise * rng.normal()
        d[6] = 0.0
        states[t], next_states[t] = s, s + d
        s = s + d
    return {
        "states": states.astype(np.float32), "actions": actions.astype(np.float32),
        "next_states": next_states.astype(np.float32),
        "episodes": (np.arange(rows) // episode_len).astype(np.uint32),
        "steps": (np.arange(rows) % episode_len).astype(np.uint32),
        "holding": np.zeros(rows, dtype=np.uint8),
        "stamps_ns": (np.arange(rows) * 10_000_000).astype(np.uint64),
    }


def write(path: pathlib.Path, tensors: dict[str, np.ndarray], experiment: str = "exp1"
          ) -> pathlib.Path:
    from safetensors.numpy import save_file

    save_file(tensors, str(path), metadata={"format": "causal_arm.dataset.v2",
                                            "experiment": experiment,
                                            "action_source": "babbler"})
    return path


@pytest.fixture(scope="module")
def dataset(tmp_path_factory) -> pathlib.Path:
    return write(tmp_path_factory.mktemp("anchors") / "exp1.safetensors", make_transitions())


def run(methods: str, data: pathlib.Path, out: pathlib.Path, *extra: str) -> list[dict]:
    code = anchors.main(["--data", str(data), "--out", str(out), "--methods", methods, *extra])
    assert code == 0
    return json.loads((out / "anchors.json").read_text())


def claimed(claims: dict) -> set[tuple[str, str]]:
    return {(a, s) for i, a in enumerate(claims["action_names"])
            for k, s in enumerate(claims["state_names"]) if claims["drives"][i][k]}


def check_layout(claims: dict, rows: int) -> None:
    assert set(claims) == {"method", "rule", "context", "horizon", "observations",
                           "action_names", "state_names", "score", "interval", "drives",
                           "seconds"}
    assert (claims["context"], claims["horizon"], claims["interval"]) == ("all", 1, None)
    assert claims["action_names"] == ACTIONS and claims["state_names"] == STATES
    assert 0 < claims["observations"] <= rows and claims["rule"]
    score = np.array(claims["score"])
    assert score.shape == (7, 10) and np.isfinite(score).all()
    assert np.array(claims["drives"]).shape == (7, 10)


GRAPH_METHODS = ["pcmci", "pc"]


@pytest.fixture(scope="module")
def results(dataset, tmp_path_factory) -> dict[str, dict]:
    """Every installed method once on the 5,000-row dataset (perm on 3,000 of them)."""
    out = tmp_path_factory.mktemp("results")
    fast = run(",".join(["granger", "granger-x"] + GRAPH_METHODS), dataset, out / "fast")
    perm = run("perm", dataset, out / "perm", "--max-rows", "3000")
    return {r["method"]: r for r in fast + perm}


def test_every_claim_set_has_the_edge_claims_layout(results):
    assert set(results) == {"granger", "granger-x", "perm", *GRAPH_METHODS}
    for r in results.values():
        check_layout(r, 5000)
    assert results["granger"]["observations"] == 5000
    assert results["perm"]["observations"] == 3000


def test_granger_sees_the_linear_edge_and_granger_x_the_interaction(results):
    assert claimed(results["granger"]) == {("a0", "theta0")}
    assert claimed(results["granger-x"]) == TRUE_EDGES
    # The score ranks the true edges above every other pair.
    score = np.array(results["granger-x"]["score"])
    assert score[1, 7] > np.delete(score.ravel(), [0 * 10 + 0, 1 * 10 + 7]).max()


def test_perm_finds_both_edges_and_nothing_else(results):
    assert claimed(results["perm"]) == TRUE_EDGES


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_perm_never_claims_an_action_without_effect(tmp_path, seed):
    data = write(tmp_path / "d.safetensors", make_transitions(rows=1500, seed=seed))
    (r,) = run("perm", data, tmp_path, "--seed", str(seed))
    assert claimed(r) <= TRUE_EDGES


@pytest.mark.parametrize("method", ["pcmci", "pc"])
def test_linear_graph_methods_claim_only_true_edges(results, method):
    # tests/python/requirements.txt installs tigramite and causal-learn: a missing one is
    # a broken test venv, not a reason to skip.
    assert method in results, f"{method} did not run: is its package installed?"

    # Linear tests can't see a1 -> ef_x (zero on average), but must see a0 -> theta0.
    assert claimed(results[method]) == {("a0", "theta0")}


def test_granger_ignores_effects_below_float32_resolution():
    """Realized actions make Δtheta_j = a_j up to float32 rounding, so the full model
    explains it to rounding noise; an 'effect' of 1e-8 of another action (below the
    data's resolution) must not be claimed (without the floor, 9 such edges came out of
    the quick exp1 data)."""
    rng = np.random.default_rng(0)
    n = 2000
    states, actions = rng.normal(size=(n, 10)), rng.uniform(-1, 1, size=(n, 7))
    deltas = 0.01 * rng.normal(size=(n, 10))
    deltas[:, 0] = actions[:, 0] + 1e-8 * actions[:, 1] * states[:, 3]
    data = anchors.Transitions(pathlib.Path("in-memory"), "exp1", states, actions, deltas,
                               np.zeros(n, dtype=np.int64), np.arange(n), ACTIONS, STATES)
    for run_method in (anchors.run_granger, anchors.run_granger_x):
        drives = run_method(data, anchors.Settings(), n).drives
        assert drives[0, 0] and drives.sum() == 1


def test_a_feature_that_never_changes_is_never_claimed(results):
    theta6 = STATES.index("theta6")
    for r in results.values():
        assert not any(row[theta6] for row in r["drives"]), r["method"]
        assert all(row[theta6] == 0.0 for row in r["score"]), r["method"]


def test_exp2_angles_are_wrapped_and_the_colour_is_never_claimed(tmp_path):
    rng = np.random.default_rng(0)
    n = 400
    states = rng.uniform(-1, 1, size=(n, 23)).astype(np.float32)
    states[:, 6:9] = [0.8, 0.1, 0.1]  # the cube's colour never changes
    states[:, 5] = np.pi - 0.01  # o_rz just below π ...
    actions = rng.uniform(-1, 1, size=(n, 8)).astype(np.float32)
    next_states = states + 0.01 * rng.normal(size=(n, 23)).astype(np.float32)
    next_states[:, 6:9] = states[:, 6:9]
    next_states[:, 5] = -np.pi + 0.01 + 0.001 * actions[:, 0]  # ... turns past it
    tensors = make_transitions(rows=n)
    tensors.update(states=states, actions=actions, next_states=next_states)
    data = anchors.load_transitions(write(tmp_path / "exp2.safetensors", tensors, "exp2"))
    assert data.state_names[5] == "o_rz" and data.action_names[-1] == "a_mgt"
    assert np.allclose(data.deltas[:, 5], 0.02 + 0.001 * actions[:, 0], atol=1e-5)
    (r,) = run("granger", tmp_path / "exp2.safetensors", tmp_path)
    assert ("a0", "o_rz") in claimed(r)
    colour = [data.state_names.index(c) for c in ("o_R", "o_G", "o_B")]
    assert not any(row[k] for row in r["drives"] for k in colour)


def test_a_missing_package_is_one_clear_line_and_a_failure(dataset, tmp_path, monkeypatch,
                                                           capsys):
    monkeypatch.setitem(sys.modules, "tigramite", None)
    code = anchors.main(["--data", str(dataset), "--out", str(tmp_path), "--methods",
                         "granger,pcmci"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code != 0 and not (tmp_path / "anchors.json").exists()
    assert len(err) == 1
    assert "pcmci" in err[0] and "'tigramite'" in err[0]
    assert "pip install -r tests/bench/requirements-anchors.txt" in err[0]
    # With --skip-missing the other methods still run.
    (r,) = run("granger,pcmci", dataset, tmp_path, "--skip-missing")
    assert r["method"] == "granger"


def cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(TOOL), *args], capture_output=True, text=True,
                          timeout=60)


def test_a_file_without_actions_is_named_with_the_missing_tensor(tmp_path):
    tensors = make_transitions(rows=100)
    del tensors["actions"]
    data = write(tmp_path / "no_actions.safetensors", tensors)
    r = cli("--data", str(data), "--out", str(tmp_path / "out"), "--methods", "granger")
    assert r.returncode != 0
    assert str(data) in r.stderr and "'actions'" in r.stderr
    assert "Traceback" not in r.stderr


@pytest.mark.parametrize("problem", ["missing", "experiment", "shape", "empty", "method"])
def test_bad_input_is_a_clear_error(tmp_path, problem):
    tensors, experiment = make_transitions(rows=100), "exp1"
    if problem == "experiment":
        experiment = "exp9"
    elif problem == "shape":
        tensors["states"] = tensors["states"][:, :9]
    elif problem == "empty":
        tensors = {k: v[:0] for k, v in tensors.items()}
    data = tmp_path / "d.safetensors"
    if problem != "missing":
        write(data, tensors, experiment)
    methods = "granger,bogus" if problem == "method" else "granger"
    r = cli("--data", str(data), "--out", str(tmp_path / "out"), "--methods", methods)
    assert r.returncode != 0 and "Traceback" not in r.stderr
    expected = {"missing": "no such file", "experiment": "exp9", "shape": "'states'",
                "empty": "0 rows", "method": "bogus"}[problem]
    assert expected in r.stderr
    if problem != "method":
        assert str(data) in r.stderr
