#!/usr/bin/env python3
r"""Standard causal-discovery anchors for the project's action -> state-change verdicts.

The project claims, for every action a_j and state feature s_k, whether a_j drives the
one-step change Δs_k = s_k(t+1) - s_k(t) (Euler angles wrapped into (-π, π]). This tool
runs five standard methods on the same transitions (a dataset cache written by
`causal-arm train`) and writes their claims in the Rust `EdgeClaims` layout, so the
project's verdicts can be scored side by side with textbook baselines:

  granger    Linear Granger: OLS of Δs_k on [1, s(t), a(t)], F-test of dropping a_j.
             Why: the simplest "does a_j add predictive power given the state" test; it
             only sees effects that are linear on average. Bonferroni over all na x ns
             pairs at family-wise alpha. Default cap 200,000 rows.
  granger-x  Granger with action x state interactions: regressors [1, s, a, a_j*s_i for
             all j, i] (columns standardised); the F-test drops a_j and every a_j*s_i
             together. Why: a joint-angle delta moves the effector through the Jacobian,
             i.e. through a_j*f(theta), which the linear test averages away. Bonferroni.
             Default cap 100,000 rows.
  pcmci      tigramite PCMCI + ParCorr, tau_max = 1, on the time series of each episode.
             Variables: the arriving change D_k(t) = Δs_k(t-1) (non-constant features),
             the state levels L_i(t) = s_i(t) and the actions A_j(t). Links are allowed
             only into D at lag 1 (from every A, L and D); nothing at lag 0 and nothing
             into L or A, so A_j(t-1) -> D_k(t) is exactly "a_j(t) drives Δs_k(t)", tested
             given the PC-selected lag-1 parents. Episodes (and runs of consecutive steps
             inside them) are concatenated with tigramite's missing-value flag between
             them, so no sample pairs rows of two episodes. Why: the standard time-series
             causal-discovery baseline (conditions on autocorrelation and state). pc_alpha
             0.2 (tigramite's default) for condition selection; the MCI p-values of the
             na x ns action -> state links are Bonferroni-corrected at alpha. Default cap
             20,000 rows (whole episodes in seeded random order).
  perm       Permutation importance with a placebo floor: per target, a
             HistGradientBoostingRegressor (sklearn defaults, no early stopping) on
             [s, a, 5 placebo columns] -> Δs_k, cross-fitted: fitted on one random half
             of the rows, importances on the other, and the other way round.
             Importance = increase of held-out MSE when a column is permuted (5 repeats).
             Placebo p is a permuted copy of an action (spread from a0 to the
             last action): an input with a real action's marginal and no effect. A fold
             claims a_j when its smallest importance exceeds max(2 F, F + 3 sd,
             0.001 Var(Δs_k)), F = the largest placebo importance over all repeats, sd =
             the placebos' spread; a_j -> s_k is claimed when both folds claim it (one
             fold alone let a null column the model happened to lean on through: the
             test-set chance correlation is the same in every repeat). Why: a nonlinear,
             model-based anchor that needs no parametric test. Default cap 20,000 rows.
  pc         causal-learn PC (Fisher z) run per target on [a, s, Δs_k], with background
             knowledge: nothing causes an action, only s causes s, Δs_k causes nothing.
             a_j -> Δs_k is claimed when PC keeps the edge (oriented from a_j or
             undirected; actions cannot be effects). One run per target because the Δs
             of one step have no edges among themselves (s(t+1) is made from s(t) and
             a(t)), and because with realized actions Δtheta_j is a copy of a_j: in one
             joint graph that copy "explains away" every a_j -> Δef edge (PC found only
             the 7 a_j -> theta_j edges in exp1). The Fisher z uses a pseudo-inverse, as
             such ties make the stock test's correlation matrix singular. Why: the
             standard constraint-based DAG learner. Per-test alpha = alpha / (na x ns)
             (Bonferroni, so its false-positive rate matches the others). Default cap
             5,000 rows.

Methods run with 1 BLAS/OpenMP thread unless --threads says otherwise (on a busy 2-core
machine 2 threads made pcmci and perm 5-8x slower). Every method subsamples rows with
--seed when the data exceed its cap (--max-rows N sets every cap to N). A feature whose
Δ is constant on the rows a method uses (e.g. the cube's colour) is never claimed and
scores 0. Scores are -log10 p (Granger, PCMCI, PC; the largest p over PC's tests of the
pair) or the placebo-corrected importance as a fraction of Var(Δs_k) (perm); higher =
more evidence, always finite. The project's default datasets hold realized actions, so
Δtheta_j = a_j up to float32 rounding: the Granger tests treat a residual below 1e-12 of
a target's variance as rounding noise, and PC's Fisher z tolerates the singular ties.

  python tests/bench/causal_anchors.py \
      --data ~/.cache/causal-arm/dataset-<hash>-realized-causal_arm.dataset.v2.safetensors \
      --out /tmp/anchors [--methods granger,granger-x,pcmci,perm,pc] [--max-rows N] \
      [--alpha 0.05] [--seed 0] [--threads 1] [--skip-missing]

Install: pip install -r tests/bench/requirements-anchors.txt
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import json
import math
import pathlib
import sys
import time
from dataclasses import dataclass
from typing import Callable, Optional, Sequence

try:
    import numpy as np
except ImportError:  # reported by main() as a one-line error
    np = None  # type: ignore[assignment]

INSTALL = "pip install -r tests/bench/requirements-anchors.txt"

THETA = [f"theta{i}" for i in range(7)]
STATE_NAMES = {
    "exp1": THETA + ["ef_x", "ef_y", "ef_z"],
    "exp2": ["o_x", "o_y", "o_z", "o_rx", "o_ry", "o_rz", "o_R", "o_G", "o_B"] + THETA
    + ["ef_x", "ef_y", "ef_z", "ef_rx", "ef_ry", "ef_rz", "mgt"],
}
ACTION_NAMES = {"exp1": [f"a{i}" for i in range(7)],
                "exp2": [f"a{i}" for i in range(7)] + ["a_mgt"]}
ANGULAR = {"exp1": (), "exp2": (3, 4, 5, 19, 20, 21)}
TENSORS = ("states", "actions", "next_states", "episodes", "steps")

PERM_PLACEBOS = 5
PERM_REPEATS = 5
PERM_MIN_FRACTION = 1e-3
PERM_RULE = (
    "importance = increase of held-out MSE when a column is permuted ({r} repeats); a fold "
    "claims an action when its smallest importance exceeds max(2 x F, F + 3 x sd, "
    "{m:g} x Var(dS_k)), F = the largest importance of the {p} placebo columns over all "
    "repeats, sd = their standard deviation; claim when both folds claim"
)
LOG10 = math.log(10.0)
SCORE_CAP = 1e6


class AnchorError(Exception):
    """A user error (bad input, missing package): reported as one line, no traceback."""


@dataclass
class Transitions:
    """One dataset of transitions, Δ already computed (float64, angles wrapped)."""

    path: pathlib.Path
    experiment: str
    states: np.ndarray
    actions: np.ndarray
    deltas: np.ndarray
    episodes: np.ndarray
    steps: np.ndarray
    action_names: list[str]
    state_names: list[str]

    @property
    def rows(self) -> int:
        return int(self.states.shape[0])


@dataclass
class Settings:
    alpha: float = 0.05
    seed: int = 0
    max_rows: Optional[int] = None
    threads: int = 1


@dataclass
class Result:
    """What one method found: [action][state] matrices plus the rule and rows used."""

    score: np.ndarray
    drives: np.ndarray
    observations: int
    rule: str


@dataclass(frozen=True)
class Method:
    name: str
    run: Callable[[Transitions, Settings, int], Result]  # (data, settings, row cap)
    modules: tuple[tuple[str, str], ...]  # (import name, pip package)
    default_cap: int  # rows, unless --max-rows

    def cap(self, settings: Settings) -> int:
        return settings.max_rows if settings.max_rows is not None else self.default_cap


# ---------------------------------------------------------------- input


def wrap_angle(delta: np.ndarray) -> np.ndarray:
    """Maps angle differences into (-π, π], as the Rust side does."""
    tau = 2.0 * math.pi
    wrapped = delta - tau * np.round(delta / tau)
    return np.where(wrapped <= -math.pi, wrapped + tau, wrapped)


def _read_tensors(path: pathlib.Path) -> tuple[dict, dict[str, np.ndarray]]:
    from safetensors import SafetensorError, safe_open

    if not path.is_file():
        raise AnchorError(f"{path}: no such file")
    try:
        with safe_open(str(path), framework="numpy") as f:
            meta = f.metadata() or {}
            keys = set(f.keys())
            missing = [t for t in TENSORS if t not in keys]
            if missing:
                raise AnchorError(f"{path}: no tensor {', '.join(map(repr, missing))} "
                                  f"(has {', '.join(sorted(keys)) or 'none'})")
            tensors = {t: f.get_tensor(t) for t in TENSORS}
    except (SafetensorError, OSError, ValueError, TypeError) as e:
        raise AnchorError(f"{path}: not a readable safetensors dataset ({e})") from None
    return meta, tensors


def _check_shapes(path: pathlib.Path, t: dict[str, np.ndarray], ns: int, na: int) -> int:
    n = t["states"].shape[0] if t["states"].ndim == 2 else -1
    expected = {"states": (n, ns), "next_states": (n, ns), "actions": (n, na),
                "episodes": (n,), "steps": (n,)}
    for name, shape in expected.items():
        if tuple(t[name].shape) != shape:
            raise AnchorError(f"{path}: tensor {name!r} has shape {list(t[name].shape)}, "
                              f"expected {['n' if d == n else d for d in shape]}")
    if n == 0:
        raise AnchorError(f"{path}: the dataset has 0 rows")
    for name in ("states", "next_states", "actions"):
        if not np.isfinite(t[name]).all():
            raise AnchorError(f"{path}: tensor {name!r} holds NaN or infinite values")
    return n


def load_transitions(path: pathlib.Path) -> Transitions:
    """Reads a `causal-arm` dataset cache; raises AnchorError naming the file and problem."""
    path = pathlib.Path(path)
    meta, t = _read_tensors(path)
    experiment = meta.get("experiment")
    if experiment not in STATE_NAMES:
        raise AnchorError(f"{path}: unknown experiment {experiment!r} in the metadata "
                          f"(expected one of {', '.join(STATE_NAMES)})")
    ns, na = len(STATE_NAMES[experiment]), len(ACTION_NAMES[experiment])
    _check_shapes(path, t, ns, na)
    states = t["states"].astype(np.float64)
    deltas = t["next_states"].astype(np.float64) - states
    for k in ANGULAR[experiment]:
        deltas[:, k] = wrap_angle(deltas[:, k])
    return Transitions(path, experiment, states, t["actions"].astype(np.float64), deltas,
                       t["episodes"].astype(np.int64), t["steps"].astype(np.int64),
                       list(ACTION_NAMES[experiment]), list(STATE_NAMES[experiment]))


# ---------------------------------------------------------------- shared helpers


def subsample(n: int, cap: int, seed: int) -> np.ndarray:
    """Sorted row indices: all rows, or `cap` of them drawn without replacement."""
    if n <= cap:
        return np.arange(n)
    return np.sort(np.random.default_rng(seed).choice(n, size=cap, replace=False))


def varying(x: np.ndarray) -> np.ndarray:
    """Columns that are not constant (a Δ that never changes can't be claimed)."""
    return np.ptp(x, axis=0) > 0


def standardize(x: np.ndarray) -> np.ndarray:
    """Zero-mean unit-variance columns (constant columns become 0)."""
    sd = x.std(axis=0)
    return (x - x.mean(axis=0)) / np.where(sd > 0, sd, 1.0)


def neg_log10(log_p: np.ndarray) -> np.ndarray:
    """-log10 p from natural log p, finite and >= 0."""
    return np.clip(-np.asarray(log_p, dtype=np.float64) / LOG10, 0.0, SCORE_CAP)


def chi2_log_sf(stat: np.ndarray, df: np.ndarray) -> np.ndarray:
    """log P(chi2_df > stat) by the Wilson-Hilferty normal approximation, which never
    underflows (used where the exact tail probability is below float range)."""
    from scipy import stats

    df = np.maximum(np.asarray(df, dtype=np.float64), 1.0)
    z = ((np.maximum(stat, 0.0) / df) ** (1 / 3) - (1 - 2 / (9 * df))) / np.sqrt(2 / (9 * df))
    return stats.norm.logsf(z)


def limit_threads(threads: int):
    """Caps BLAS and OpenMP threads of the libraries loaded so far (no-op without
    threadpoolctl). On a busy 2-core machine their spinning thread barriers made 2-thread
    runs 5-8x slower than 1-thread ones (pcmci on exp2: 110 s vs 20 s; perm: 132 s vs 17 s)."""
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:
        return contextlib.nullcontext()
    return threadpool_limits(limits=threads)


def _bonferroni(alpha: float, pairs: int) -> float:
    return alpha / max(pairs, 1)


# ---------------------------------------------------------------- granger


def _rss(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, int]:
    """Residual sum of squares of the OLS fit of every column of y on x, and x's rank."""
    coef, _, rank, _ = np.linalg.lstsq(x, y, rcond=None)
    resid = y - x @ coef
    return np.einsum("ij,ij->j", resid, resid), int(rank)


def _granger_design(s: np.ndarray, a: np.ndarray, interactions: bool) -> tuple[np.ndarray, list]:
    """Design [1, s, a (, a_j*s_i)] and, per action, the columns that belong to it (None
    for an action that is constant here and so can't be tested)."""
    zs, za = standardize(s[:, varying(s)]), standardize(a)
    live = varying(a)
    cols, blocks = [np.ones((len(s), 1)), zs], []
    width = 1 + zs.shape[1]
    for j in range(a.shape[1]):
        if not live[j]:
            blocks.append(None)
            continue
        part = [za[:, j:j + 1]] + ([za[:, j:j + 1] * zs] if interactions else [])
        block = np.hstack(part)
        cols.append(block)
        blocks.append(np.arange(width, width + block.shape[1]))
        width += block.shape[1]
    return np.hstack(cols), blocks


def _f_test_log_p(rss_r: np.ndarray, rss_f: np.ndarray, df1: int, df2: int) -> np.ndarray:
    """Natural log of the F-test p-value per target (exact, or asymptotic past underflow)."""
    from scipy import stats

    if df1 <= 0:
        return np.zeros_like(rss_f)
    f = np.maximum(rss_r - rss_f, 0.0) / df1 / (rss_f / df2)
    log_p = stats.f.logsf(f, df1, df2)
    return np.where(np.isfinite(log_p), log_p, chi2_log_sf(f * df1, df1))


def run_granger_common(data: Transitions, settings: Settings, cap: int,
                       interactions: bool) -> Result:
    rows = subsample(data.rows, cap, settings.seed)
    s, a, d = data.states[rows], data.actions[rows], data.deltas[rows]
    targets = varying(d)
    na, ns = a.shape[1], d.shape[1]
    score, drives = np.zeros((na, ns)), np.zeros((na, ns), dtype=bool)
    x, blocks = _granger_design(s, a, interactions)
    if len(rows) <= x.shape[1] + 1:
        raise AnchorError(f"{data.path}: {'granger-x' if interactions else 'granger'} needs "
                          f"more than {x.shape[1] + 1} rows ({x.shape[1]} regressors), got "
                          f"{len(rows)}")
    y = d[:, targets]
    tss = ((y - y.mean(axis=0)) ** 2).sum(axis=0)
    rss_f, rank_f = _rss(x, y)
    # The data are float32 (~1e-7 relative): a residual below 1e-12 of a target's variance
    # is rounding noise. With realized actions Δtheta_j = a_j to that precision, and
    # without this floor the F-tests on the rounding noise "find" a_i -> theta_j edges
    # (9 false ones on the quick exp1 data).
    rss_f = np.maximum(rss_f, 1e-12 * tss)
    threshold = math.log(_bonferroni(settings.alpha, na * ns))
    for j, block in enumerate(blocks):
        if block is None or not targets.any():
            continue
        rss_r, rank_r = _rss(np.delete(x, block, axis=1), y)
        log_p = _f_test_log_p(rss_r, rss_f, rank_f - rank_r, len(rows) - rank_f)
        score[j, targets] = neg_log10(log_p)
        drives[j, targets] = log_p < threshold
    what = ("[1, s, a, a_j*s_i] (standardised); F-test drops a_j and all a_j*s_i"
            if interactions else "[1, s, a]; F-test drops a_j")
    rule = (f"OLS of dS_k on {what}; claim when p < alpha/(na x ns) = {settings.alpha:g}/"
            f"{na * ns} (Bonferroni); residual variance floored at 1e-12 Var(dS_k) (float32 "
            f"rounding); score -log10 p; {len(rows)} rows "
            f"(cap {cap}, seed {settings.seed})")
    return Result(score, drives, len(rows), rule)


def run_granger(data: Transitions, settings: Settings, cap: int) -> Result:
    return run_granger_common(data, settings, cap, interactions=False)


def run_granger_x(data: Transitions, settings: Settings, cap: int) -> Result:
    return run_granger_common(data, settings, cap, interactions=True)


# ---------------------------------------------------------------- pcmci

PCMCI_MISSING = -9.87654321e9
PCMCI_PC_ALPHA = 0.2


def segments(episodes: np.ndarray, steps: np.ndarray) -> list[tuple[int, int]]:
    """[start, end) runs of rows of one episode with consecutive steps."""
    breaks = (np.diff(episodes) != 0) | (np.diff(steps) != 1)
    starts = np.concatenate([[0], np.flatnonzero(breaks) + 1])
    ends = np.concatenate([starts[1:], [len(episodes)]])
    return list(zip(starts.tolist(), ends.tolist()))


def pick_segments(segs: list[tuple[int, int]], cap: int, seed: int) -> list[tuple[int, int]]:
    """Whole segments in seeded random order until `cap` rows (the last one truncated)."""
    if sum(e - s for s, e in segs) <= cap:
        return segs
    picked, total = [], 0
    for i in np.random.default_rng(seed).permutation(len(segs)):
        s, e = segs[i]
        take = min(e - s, cap - total)
        picked.append((s, s + take))
        total += take
        if total >= cap:
            break
    return sorted(picked)


def pcmci_array(data: Transitions, segs: list[tuple[int, int]], d_cols: np.ndarray,
                l_cols: np.ndarray, a_cols: np.ndarray) -> np.ndarray:
    """The series [D | L | A]: per segment of m transitions, m + 1 time steps where
    L(t), A(t) = s(t), a(t) of row t and D(t) = Δ of row t-1; cells with no value carry
    the missing flag, so no sample pairs two segments."""
    blocks = []
    for s, e in segs:
        m = e - s
        block = np.full((m + 1, len(d_cols) + len(l_cols) + len(a_cols)), PCMCI_MISSING)
        nd, nl = len(d_cols), len(l_cols)
        block[1:, :nd] = data.deltas[s:e][:, d_cols]
        block[:m, nd:nd + nl] = data.states[s:e][:, l_cols]
        block[:m, nd + nl:] = data.actions[s:e][:, a_cols]
        blocks.append(block)
    return np.vstack(blocks)


def pcmci_links(nd: int, n_vars: int) -> dict[int, dict[tuple[int, int], str]]:
    """Links into D (variables 0..nd-1) from every variable at lag 1; nothing else."""
    return {j: ({(i, -1): "-?>" for i in range(n_vars)} if j < nd else {})
            for j in range(n_vars)}


def _pcmci_score(p: np.ndarray, r: np.ndarray, n: int) -> np.ndarray:
    """-log10 p; where p underflowed to 0, the Fisher-z tail of the partial correlation."""
    from scipy import stats

    z = np.arctanh(np.clip(np.abs(r), 0.0, 1 - 1e-16)) * math.sqrt(max(n - 3, 1))
    log_p = np.where(p > 0, np.log(np.maximum(p, 1e-320)), math.log(2.0) + stats.norm.logsf(z))
    return neg_log10(log_p)


def run_pcmci(data: Transitions, settings: Settings, cap: int) -> Result:
    from tigramite import data_processing as pp
    from tigramite.independence_tests.parcorr import ParCorr
    from tigramite.pcmci import PCMCI

    segs = pick_segments(segments(data.episodes, data.steps), cap, settings.seed)
    rows = np.concatenate([np.arange(s, e) for s, e in segs])
    d_cols = np.flatnonzero(varying(data.deltas[rows]))
    l_cols = np.flatnonzero(varying(data.states[rows]))
    a_cols = np.flatnonzero(varying(data.actions[rows]))
    na, ns = data.actions.shape[1], data.deltas.shape[1]
    score, drives = np.zeros((na, ns)), np.zeros((na, ns), dtype=bool)
    series = pcmci_array(data, segs, d_cols, l_cols, a_cols)
    n_vars, nd = series.shape[1], len(d_cols)
    if nd and len(a_cols):
        frame = pp.DataFrame(series, missing_flag=PCMCI_MISSING)
        pcmci = PCMCI(dataframe=frame, cond_ind_test=ParCorr(significance="analytic"),
                      verbosity=0)
        out = pcmci.run_pcmci(link_assumptions=pcmci_links(nd, n_vars), tau_min=1, tau_max=1,
                              pc_alpha=PCMCI_PC_ALPHA, alpha_level=settings.alpha)
        a_vars = n_vars - len(a_cols) + np.arange(len(a_cols))
        p = np.nan_to_num(out["p_matrix"][np.ix_(a_vars, np.arange(nd), [1])][..., 0], nan=1.0)
        r = np.nan_to_num(out["val_matrix"][np.ix_(a_vars, np.arange(nd), [1])][..., 0])
        score[np.ix_(a_cols, d_cols)] = _pcmci_score(p, r, len(rows))
        drives[np.ix_(a_cols, d_cols)] = p < _bonferroni(settings.alpha, na * ns)
    rule = (f"tigramite PCMCI, ParCorr (analytic), tau_min=tau_max=1, pc_alpha="
            f"{PCMCI_PC_ALPHA:g}; variables D_k(t)=dS_k(t-1), levels s(t), actions a(t); "
            f"links only into D at lag 1; claim a_j(t-1)->D_k(t) when the MCI p < "
            f"{settings.alpha:g}/{na * ns} (Bonferroni over na x ns); score -log10 p; "
            f"{len(segs)} episode segments concatenated with tigramite's missing-value flag "
            f"between them; {len(rows)} rows (cap {cap}: whole episodes in random order, "
            f"the last one cut; seed {settings.seed})")
    return Result(score, drives, len(rows), rule)


# ---------------------------------------------------------------- perm


def placebo_sources(na: int, count: int = PERM_PLACEBOS) -> list[int]:
    """Actions whose permuted copies are the placebos: spread from a0 to the last."""
    return [round(i * (na - 1) / max(count - 1, 1)) for i in range(count)]


def permutation_importance(model, x: np.ndarray, y: np.ndarray, cols: Sequence[int],
                           repeats: int, rng: np.random.Generator) -> np.ndarray:
    """[len(cols), repeats] increase of held-out MSE when column c is permuted (the
    repeats of a column are predicted in one call: the per-call cost of a boosted model's
    predict dominates otherwise)."""
    n = len(x)
    base = float(np.mean((model.predict(x) - y) ** 2))
    out = np.zeros((len(cols), repeats))
    stacked = np.tile(x, (repeats, 1))
    for i, c in enumerate(cols):
        stacked[:, c] = np.concatenate([x[rng.permutation(n), c] for _ in range(repeats)])
        err = (model.predict(stacked).reshape(repeats, n) - y) ** 2
        out[i] = err.mean(axis=1) - base
        stacked[:, c] = np.tile(x[:, c], repeats)
    return out


def perm_verdict(actions: np.ndarray, placebos: np.ndarray, var_y: float
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Score and claim per action of one fold, from [actions, repeats] and
    [placebos, repeats] held-out importances (see PERM_RULE)."""
    floor = float(placebos.max())
    margin = max(2.0 * floor, floor + 3.0 * float(placebos.std()), PERM_MIN_FRACTION * var_y)
    claim = actions.min(axis=1) > margin
    score = (actions.mean(axis=1) - floor) / max(var_y, 1e-300)
    return np.clip(score, -SCORE_CAP, SCORE_CAP), claim


def _perm_inputs(data: Transitions, rows: np.ndarray, rng: np.random.Generator
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """[s (varying), a, placebos], the action columns and the placebo columns."""
    s, a = data.states[rows], data.actions[rows]
    s = s[:, varying(s)]
    placebo = np.column_stack([a[rng.permutation(len(a)), j]
                               for j in placebo_sources(a.shape[1])])
    x = np.hstack([s, a, placebo])
    a_cols = s.shape[1] + np.arange(a.shape[1])
    return x, a_cols, a_cols[-1] + 1 + np.arange(placebo.shape[1])


def _perm_target(x: np.ndarray, y: np.ndarray, half: np.ndarray, cols: list[int], na: int,
                 seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Cross-fitted verdict for one target: a model per half, importances on the other
    half; an action is claimed when both folds claim it, its score is the folds' mean."""
    from sklearn.ensemble import HistGradientBoostingRegressor

    rng = np.random.default_rng(seed)
    scores, claims = [], []
    for train in (half, ~half):
        model = HistGradientBoostingRegressor(early_stopping=False, random_state=seed)
        model.fit(x[train], y[train])
        imp = permutation_importance(model, x[~train], y[~train], cols, PERM_REPEATS, rng)
        score, claim = perm_verdict(imp[:na], imp[na:], float(y[~train].var()))
        scores.append(score)
        claims.append(claim)
    return np.mean(scores, axis=0), np.logical_and.reduce(claims)


def run_perm(data: Transitions, settings: Settings, cap: int) -> Result:
    import sklearn.ensemble  # noqa: F401  (loads the OpenMP runtime the limit applies to)

    with limit_threads(settings.threads):
        return _run_perm(data, settings, cap)


def _run_perm(data: Transitions, settings: Settings, cap: int) -> Result:
    rows = subsample(data.rows, cap, settings.seed)
    rng = np.random.default_rng(settings.seed)
    x, a_cols, p_cols = _perm_inputs(data, rows, rng)
    d = data.deltas[rows]
    half = np.zeros(len(rows), dtype=bool)
    half[rng.choice(len(rows), size=len(rows) // 2, replace=False)] = True
    na, ns = len(a_cols), d.shape[1]
    score, drives = np.zeros((na, ns)), np.zeros((na, ns), dtype=bool)
    for k in np.flatnonzero(varying(d[half]) & varying(d[~half])):
        score[:, k], drives[:, k] = _perm_target(x, d[:, k], half, list(a_cols) + list(p_cols),
                                                 na, settings.seed + k)
        print(f"[anchors] perm: {data.state_names[k]} done", file=sys.stderr)
    rule = (f"HistGradientBoostingRegressor (defaults, no early stopping) on [s, a, "
            f"{PERM_PLACEBOS} placebos = permuted copies of a{placebo_sources(na)}] -> dS_k, "
            f"cross-fitted on two random halves (fit on one, importance on the other); "
            + PERM_RULE.format(r=PERM_REPEATS, m=PERM_MIN_FRACTION, p=PERM_PLACEBOS)
            + f"; score: mean over folds of (mean importance - F) / Var(dS_k); {len(rows)} "
            f"rows (cap {cap}, seed {settings.seed})")
    return Result(score, drives, len(rows), rule)


# ---------------------------------------------------------------- pc


def pc_background():
    """Nothing causes an action; nothing but s causes s; Δ causes nothing."""
    from causallearn.utils.PCUtils.BackgroundKnowledge import BackgroundKnowledge

    bk = BackgroundKnowledge()
    bk.add_forbidden_by_pattern(r".*", r"A:.*")
    bk.add_forbidden_by_pattern(r"[AD]:.*", r"S:.*")
    return bk


def partial_corr(corr: np.ndarray, x: int, y: int, z: Sequence[int]) -> float:
    """Partial correlation of x and y given z from a correlation matrix (Schur complement
    with a pseudo-inverse); 0 where x or y is (numerically) a linear function of z."""
    xy = [x, y]
    m = corr[np.ix_(xy, xy)]
    if len(z):
        m = m - corr[np.ix_(xy, z)] @ np.linalg.pinv(corr[np.ix_(z, z)]) @ corr[np.ix_(z, xy)]
    if min(m[0, 0], m[1, 1]) < 1e-10:
        return 0.0
    return float(np.clip(m[0, 1] / math.sqrt(m[0, 0] * m[1, 1]), -1.0, 1.0))


def fisher_z_stat(r: float, n: int, conditions: int) -> float:
    return math.sqrt(max(n - conditions - 3, 1)) * math.atanh(min(abs(r), 1 - 1e-16))


def register_robust_fisherz() -> str:
    """Registers (once) causal-learn's Fisher z with a pseudo-inverse and returns its name:
    deterministic ties (realized actions: Δtheta_j = a_j; the magnet) make the stock
    test's correlation submatrix singular. It also records, per pair, the smallest
    statistic over the tests PC ran (= the largest p: the pair's score)."""
    from causallearn.utils.cit import FisherZ, register_ci_test

    class RobustFisherZ(FisherZ):
        def __init__(self, data: np.ndarray, **kwargs) -> None:
            super().__init__(data, **kwargs)
            self.smallest: dict[tuple[int, int], float] = {}

        def __call__(self, X, Y, condition_set=None) -> float:
            xs, ys, z, key = self.get_formatted_XYZ_and_cachekey(X, Y, condition_set)
            if key not in self.pvalue_cache:
                r = partial_corr(self.correlation_matrix, xs[0], ys[0], z)
                stat = fisher_z_stat(r, self.sample_size, len(z))
                pair = (xs[0], ys[0])
                self.smallest[pair] = min(stat, self.smallest.get(pair, math.inf))
                self.pvalue_cache[key] = math.erfc(stat / math.sqrt(2.0))
            return self.pvalue_cache[key]

    register_ci_test("fisherz-robust", RobustFisherZ)
    return "fisherz-robust"


def fisher_z_score(stat: float) -> float:
    """-log10 of the two-sided Fisher-z p-value of a statistic (never underflows)."""
    from scipy import stats

    if stat <= 0:
        return 0.0
    return float(neg_log10(math.log(2.0) + stats.norm.logsf(stat)))


def pc_target(base: np.ndarray, names: list[str], target: np.ndarray, target_name: str,
              n_actions: int, alpha: float) -> tuple[np.ndarray, np.ndarray]:
    """PC on [a, s, Δs_k] for one target: per action column of `base` (the first
    n_actions), the -log10 of the largest p over PC's tests of a_j -- Δs_k and whether
    PC keeps the edge (a_j --> Δs_k, or undirected)."""
    from causallearn.search.ConstraintBased.PC import pc

    x = np.hstack([base, target[:, None]])
    dn = x.shape[1] - 1
    cg = pc(x, alpha, register_robust_fisherz(), background_knowledge=pc_background(),
            node_names=names + [f"D:{target_name}"], show_progress=False)
    g = cg.G.graph
    score = np.array([fisher_z_score(cg.test.smallest.get((a, dn), 0.0))
                      for a in range(n_actions)])
    kept = np.array([g[a, dn] == -1 and g[dn, a] in (-1, 1) for a in range(n_actions)])
    return score, kept


def run_pc(data: Transitions, settings: Settings, cap: int) -> Result:
    rows = subsample(data.rows, cap, settings.seed)
    a, s, d = data.actions[rows], data.states[rows], data.deltas[rows]
    a_idx, s_idx = np.flatnonzero(varying(a)), np.flatnonzero(varying(s))
    base = np.hstack([a[:, a_idx], s[:, s_idx]])
    names = ([f"A:{data.action_names[j]}" for j in a_idx]
             + [f"S:{data.state_names[i]}" for i in s_idx])
    na, ns = a.shape[1], d.shape[1]
    score, drives = np.zeros((na, ns)), np.zeros((na, ns), dtype=bool)
    alpha = _bonferroni(settings.alpha, na * ns)
    for k in np.flatnonzero(varying(d)) if len(a_idx) else []:
        score[a_idx, k], drives[a_idx, k] = pc_target(base, names, d[:, k],
                                                      data.state_names[k], len(a_idx), alpha)
    rule = (f"causal-learn PC (stable, Fisher z with a pseudo-inverse), run per target on "
            f"[a, s, dS_k] (the dS of one step have no edges among themselves: s(t+1) is "
            f"made from s(t), a(t); "
            f"and with realized actions dtheta_j is a copy of a_j, which would let it "
            f"explain away every a_j -> dS_k edge); background knowledge: nothing -> a, "
            f"only s -> s; per-test alpha = {settings.alpha:g}/{na * ns} (Bonferroni); "
            f"claim a_j -> dS_k when PC keeps the edge (a_j --> dS_k or a_j --- dS_k); "
            f"score -log10 of the largest p over PC's tests of the pair; {len(rows)} rows "
            f"(cap {cap}, seed {settings.seed})")
    return Result(score, drives, len(rows), rule)


# ---------------------------------------------------------------- driver

METHODS: dict[str, Method] = {
    m.name: m for m in [
        Method("granger", run_granger, (("scipy", "scipy"),), 200_000),
        Method("granger-x", run_granger_x, (("scipy", "scipy"),), 100_000),
        Method("pcmci", run_pcmci, (("tigramite", "tigramite"), ("scipy", "scipy")), 20_000),
        Method("perm", run_perm, (("sklearn", "scikit-learn"),), 20_000),
        Method("pc", run_pc, (("causallearn", "causal-learn"), ("scipy", "scipy")), 5_000),
    ]
}


def missing_package(method: Method) -> Optional[str]:
    """The pip package `method` needs and can't import, or None."""
    for module, package in method.modules:
        try:
            importlib.import_module(module)
        except ImportError:
            return package
    return None


def require_io() -> None:
    """Reading the data needs numpy and safetensors, whatever the method."""
    for module in ("numpy", "safetensors"):
        try:
            importlib.import_module(module)
        except ImportError:
            raise AnchorError(f"reading the data needs the Python package '{module}', which "
                              f"is not installed: {INSTALL}") from None


def claims(name: str, data: Transitions, result: Result, seconds: float) -> dict:
    """One method's claims in the Rust `EdgeClaims` layout (+ wall time)."""
    score = np.nan_to_num(result.score, nan=0.0, posinf=SCORE_CAP, neginf=-SCORE_CAP)
    return {
        "method": name, "rule": result.rule, "context": "all", "horizon": 1,
        "observations": int(result.observations),
        "action_names": data.action_names, "state_names": data.state_names,
        "score": [[float(v) for v in row] for row in score], "interval": None,
        "drives": [[bool(v) for v in row] for row in result.drives],
        "seconds": round(seconds, 3),
    }


def run_methods(data: Transitions, names: Sequence[str], settings: Settings) -> list[dict]:
    """Runs each method in turn; returns their claim sets."""
    out = []
    for name in names:
        print(f"[anchors] {name}: running on {data.rows} rows of {data.path.name}",
              file=sys.stderr)
        start = time.perf_counter()
        method = METHODS[name]
        with limit_threads(settings.threads):
            result = method.run(data, settings, method.cap(settings))
        seconds = time.perf_counter() - start
        out.append(claims(name, data, result, seconds))
        print(f"[anchors] {name}: {int(result.drives.sum())} edges in {seconds:.1f} s",
              file=sys.stderr)
    return out


def table(results: list[dict]) -> str:
    lines = [f"{'method':<10} {'claimed':>7} {'rows':>7} {'seconds':>8}"]
    for r in results:
        edges = sum(map(sum, r["drives"]))
        lines.append(f"{r['method']:<10} {edges:>7} {r['observations']:>7} {r['seconds']:>8.1f}")
    return "\n".join(lines)


def parse_args(argv: Optional[Sequence[str]]) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--data", type=pathlib.Path, required=True,
                   help="dataset cache (.safetensors) written by causal-arm train")
    p.add_argument("--out", type=pathlib.Path, required=True, help="writes OUT/anchors.json")
    p.add_argument("--methods", default=",".join(METHODS),
                   help=f"comma-separated subset of {','.join(METHODS)}")
    p.add_argument("--max-rows", type=int, help="row cap for every method (default: per method)")
    p.add_argument("--alpha", type=float, default=0.05, help="family-wise alpha (default 0.05)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--threads", type=int, default=1,
                   help="BLAS/OpenMP threads (default 1: on a busy 2-core machine more "
                        "threads made runs 5-8x slower)")
    p.add_argument("--skip-missing", action="store_true",
                   help="skip methods whose Python package is missing instead of failing")
    return p.parse_args(argv)


def select_methods(args: argparse.Namespace) -> list[str]:
    names = [m.strip() for m in args.methods.split(",") if m.strip()]
    unknown = [m for m in names if m not in METHODS]
    if unknown or not names:
        raise AnchorError(f"unknown method {', '.join(unknown) or '(none given)'}: "
                          f"choose from {','.join(METHODS)}")
    if not 0 < args.alpha < 1:
        raise AnchorError(f"--alpha {args.alpha} is not in (0, 1)")
    if args.threads < 1:
        raise AnchorError(f"--threads {args.threads} must be at least 1")
    if args.max_rows is not None and args.max_rows < 10:
        raise AnchorError(f"--max-rows {args.max_rows} is too small (at least 10)")
    runnable = []
    for name in names:
        package = missing_package(METHODS[name])
        if package is None:
            runnable.append(name)
            continue
        message = (f"method {name} needs the Python package '{package}', which is not "
                   f"installed: {INSTALL}")
        if not args.skip_missing:
            raise AnchorError(message)
        print(f"causal_anchors: skipping {message}", file=sys.stderr)
    if not runnable:
        raise AnchorError("no method left to run (every one asked for is missing a package)")
    return runnable


def main(argv: Optional[Sequence[str]] = None) -> int:
    args = parse_args(argv)
    try:
        require_io()
        names = select_methods(args)
        data = load_transitions(args.data)
        settings = Settings(alpha=args.alpha, seed=args.seed, max_rows=args.max_rows,
                            threads=args.threads)
        results = run_methods(data, names, settings)
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / "anchors.json").write_text(json.dumps(results, indent=1) + "\n")
    except (AnchorError, OSError) as e:
        print(f"causal_anchors: error: {e}", file=sys.stderr)
        return 2
    print(table(results))
    print(f"[anchors] wrote {args.out / 'anchors.json'}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
