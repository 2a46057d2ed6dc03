#!/usr/bin/env python3
"""Causal verdicts at every budget, beside the standard causal-discovery methods.

For each cell of the grid (experiment x steps x forward-model budget) it runs, from nothing:
  generate   the babbling bag (`causal-arm generate`, in process; the same bag as `launch`)
  truth      the simulator's interventions on 500 of its states (`causal-arm intervene`)
  data       the data test and the linear Granger anchors (`causal-arm discover`)
  anchors    PCMCI, permutation importance, causal-learn PC, linear Granger in Python
             (tests/bench/causal_anchors.py, its own venv: target/anchorvenv)
  train      the forward model (1 fold) at the cell's budget: quick (the quick profile's
             epochs), e30 / e100 (30 / 100 cosine epochs)
  explain    Kernel SHAP + CAI + the data test: the default verdicts `kernel+cai+data`
and prints precision / recall / F1 / AUROC / undecided of the default beside every anchor,
with the wall time of every step, all scored by `causal-arm score` against the same truth.

Every result is appended to a JSON-lines record (--record, default
docs/runs/causal_budget/record.jsonl), so cells too long for one run are reported from
recorded runs: `--table` prints the table of everything recorded, with each cell's command.

  python3 tests/bench/causal_budget.py --cells exp1:5000,exp2:10000 --budgets quick,e30
  python3 tests/bench/causal_budget.py --table

Timings are wall times on this machine; run it on a quiet machine (nothing else building).
"""

import argparse
import json
import os
import pathlib
import subprocess
import sys
import time

ROOT = pathlib.Path(__file__).resolve().parents[2]
BIN = pathlib.Path(os.environ.get("CAUSAL_ARM_BIN", ROOT / "target" / "release" / "causal-arm"))
ANCHORS = ROOT / "tests" / "bench" / "causal_anchors.py"
ANCHOR_VENV = ROOT / "target" / "anchorvenv"
ANCHOR_REQ = ROOT / "tests" / "bench" / "requirements-anchors.txt"
GRID = {
    "exp1": [5_000, 20_000, 100_000, 500_000],
    "exp2": [10_000, 50_000, 200_000, 2_000_000],
}
BUDGETS = {"quick": [], "e30": ["--epochs", "30", "--lr-schedule", "cosine"],
           "e100": ["--epochs", "100", "--lr-schedule", "cosine"]}
DEFAULT = "kernel+cai+data"


def log(msg):
    print(msg, file=sys.stderr, flush=True)


def run(cmd, **kw):
    """Runs `cmd`, returns its wall time; a failure stops the bench naming the command."""
    started = time.monotonic()
    log("$ " + " ".join(map(str, cmd)))
    done = subprocess.run(list(map(str, cmd)), cwd=ROOT, stdout=subprocess.PIPE,
                          stderr=subprocess.STDOUT, text=True, **kw)
    if done.returncode != 0:
        sys.exit(f"error: {' '.join(map(str, cmd))} exited {done.returncode}:\n{done.stdout[-3000:]}")
    return time.monotonic() - started


def anchor_python():
    """The anchors' venv, created from the pinned requirements on first use."""
    python = ANCHOR_VENV / "bin" / "python"
    if not python.exists():
        run([sys.executable, "-m", "venv", ANCHOR_VENV])
        run([python, "-m", "pip", "install", "--quiet", "-r", ANCHOR_REQ])
    return python


def scores(claims, truth, out):
    """Scores of every claim set in `claims` (context all, block all, horizon 1)."""
    run([BIN, "score", "--claims", claims, "--truth", truth, "--out", out])
    rows = json.loads(pathlib.Path(out).read_text())
    return {r["method"]: r["scores"] for r in rows
            if r["context"] == "all" and r["block"] == "all" and r["horizon"] == 1}


def prepare_bag(exp, steps, work, seed):
    """Bag, truth and the model-free methods of one (experiment, steps): once per bag."""
    bag, truth = work / "bag", work / "truth"
    timings, results = {}, {}
    if not (bag / "metadata.yaml").exists():
        # exp 2 runs in episodes of 500 steps (pick, manoeuvre, release), exp 1 in one.
        length = ["--episodes", steps // 500] if exp == "exp2" else ["--steps", steps]
        timings["generate"] = run([BIN, "generate", exp, *length, "--seed", seed,
                                   "--out", bag, "--overwrite"])
    if not (truth / "truth.json").exists():
        timings["truth"] = run([BIN, "intervene", exp, "--bag", bag, "--states", 500,
                                "--out", truth])
    data = work / "transitions.safetensors"
    timings["data"] = run([BIN, "discover", "--bag", bag, "--truth", truth, "--out",
                           work / "discover", "--export", data])
    results.update(scores(work / "discover" / "claims.json", truth, work / "discover" / "scores.json"))
    # The anchors depend on the transitions alone: a recorded run of them is reused.
    if not (work / "anchors" / "anchors.json").exists():
        timings["anchors"] = run([anchor_python(), ANCHORS, "--data", data, "--out",
                                  work / "anchors", "--seed", seed])
    # The Python linear Granger tests cross-check the Rust ones `discover` runs: renamed.
    anchor_claims = json.loads((work / "anchors" / "anchors.json").read_text())
    for c in anchor_claims:
        if c["method"].startswith("granger"):
            c["method"] = "py-" + c["method"]
    renamed = work / "anchors" / "anchors_named.json"
    renamed.write_text(json.dumps(anchor_claims))
    results.update(scores(renamed, truth, work / "anchors" / "scores.json"))
    seconds = {c["method"]: c.get("seconds") for c in anchor_claims}
    return bag, truth, timings, results, seconds


def model_cell(exp, bag, truth, budget, work, reuse, reexplain):
    """Train the forward model at `budget` and explain it: the default verdicts. With
    `reuse`, a cell explained before is scored again without training or explaining (its
    recorded wall times kept in timings.json); with `reexplain`, a model trained before is
    explained again (its recorded training time kept), for verdict rules that changed."""
    model = work / f"model-{budget}"
    claims = model / "explain-kernel" / "claims.json"
    recorded = model / "timings.json"
    if reuse and claims.exists() and recorded.exists():
        return json.loads(recorded.read_text()), scores(
            claims, truth, model / "explain-kernel" / "scores_all.json")
    if reexplain and (model / "fm.safetensors").exists() and recorded.exists():
        timings = {"train": json.loads(recorded.read_text())["train"]}
    else:
        timings = {"train": run([BIN, "train", "--bag", bag, "--model", "fm", "--profile", "quick",
                                 "--max-folds", "1", "--out", model, *BUDGETS[budget]])}
    timings["explain"] = run([BIN, "explain", "--model", model, "--bag", bag, "--method",
                              "kernel", "--no-pair-plots", "--truth", truth])
    recorded.write_text(json.dumps(timings))
    return timings, scores(claims, truth, model / "explain-kernel" / "scores_all.json")


def record_cell(record, row):
    record.parent.mkdir(parents=True, exist_ok=True)
    with record.open("a") as f:
        f.write(json.dumps(row) + "\n")


def fmt(v):
    return "  n/a" if v is None else f"{v:5.3f}"


def print_table(rows):
    """One line per (cell, method): the default first, then the anchors, best F1 marked."""
    head = f"{'exp':<5}{'steps':>9} {'budget':<6} {'method':<22}{'prec':>6}{'recall':>7}{'F1':>6}{'AUROC':>6}{'undec':>6}  seconds"
    print(head)
    for row in rows:
        methods = row["scores"]
        order = [DEFAULT] + sorted(m for m in methods if m != DEFAULT)
        best_anchor = max((methods[m]["f1"] or 0.0 for m in methods if m not in (DEFAULT, "data")
                           and "+" not in m and "/" not in m), default=0.0)
        for m in order:
            if m not in methods:
                continue
            s = methods[m]
            secs = row["seconds"].get(m)
            mark = " <- default" if m == DEFAULT else ""
            print(f"{row['exp']:<5}{row['steps']:>9} {row['budget']:<6} {m:<22}{fmt(s['precision']):>6}"
                  f"{fmt(s['recall']):>7}{fmt(s['f1']):>6}{fmt(s['auroc']):>6}{s['undecided']:>6}"
                  f"  {'' if secs is None else f'{secs:.1f}'}{mark}")
        d = methods.get(DEFAULT, {})
        print(f"      default F1 {fmt(d.get('f1'))} vs best anchor F1 {best_anchor:5.3f}; steps: "
              + ", ".join(f"{k} {v:.1f} s" for k, v in row["timings"].items()))
        print(f"      command: {row['command']}")


ANCHOR_NAMES = ("granger", "granger-x", "py-granger", "py-granger-x", "pcmci", "perm", "pc")


def print_markdown(rows):
    """The RESULTS table: per cell the default, the data test alone, the old rule and the
    best anchor by F1, each as precision / recall / F1 (AUROC), and the wall times."""
    def prf(s):
        return f"{fmt(s['precision'])} / {fmt(s['recall'])} / {fmt(s['f1'])} ({fmt(s['auroc'])})"
    print("| exp | steps | FM | default `kernel+cai+data` P / R / F1 (AUROC) | undecided | data test alone | "
          "best anchor | old `kernel+cai` | wall: generate, data, anchors, train, explain |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        m = r["scores"]
        anchors = [(m[a]["f1"] or 0.0, a) for a in ANCHOR_NAMES if a in m]
        f1, best = max(anchors)
        t = r["timings"]
        secs = r["seconds"]
        wall = ", ".join(f"{v:.1f}" if isinstance(v, (int, float)) else "–" for v in (
            t.get("generate"), secs.get("data"), sum(v or 0 for k, v in secs.items() if k in ANCHOR_NAMES[2:]),
            t.get("train"), t.get("explain")))
        print(f"| {r['exp']} | {r['steps']:,} | {r['budget']} | {prf(m[DEFAULT])} | {m[DEFAULT]['undecided']} | "
              f"{prf(m['data'])} | {best} {prf(m[best])} | {prf(m['kernel+cai'])} | {wall} s |")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cells", default="exp1:5000,exp2:10000",
                    help="comma-separated exp:steps (the grid: exp1 5000,20000,100000,500000; "
                         "exp2 10000,50000,200000,2000000)")
    ap.add_argument("--budgets", default="quick,e30,e100")
    ap.add_argument("--seed", default="1")
    ap.add_argument("--work", default=str(ROOT / "target" / "causal_budget"))
    ap.add_argument("--record", default=str(ROOT / "docs" / "runs" / "causal_budget" / "record.jsonl"))
    ap.add_argument("--table", action="store_true", help="print the recorded table and exit")
    ap.add_argument("--markdown", action="store_true", help="with --table: as the RESULTS table")
    ap.add_argument("--history", action="store_true",
                    help="with --table: every recorded run, not only each cell's latest")
    ap.add_argument("--reuse-models", action="store_true",
                    help="score cells already trained and explained (in --work) without redoing them")
    ap.add_argument("--reexplain", action="store_true",
                    help="explain models already trained (in --work) again, keeping their recorded "
                         "training time: for a change of the verdict rules")
    args = ap.parse_args()
    record = pathlib.Path(args.record)
    if args.table:
        rows = [json.loads(l) for l in record.read_text().splitlines() if l.strip()]
        if not args.history:
            # The latest run of each cell, in the order the cells were first recorded.
            latest = {}
            for r in rows:
                latest[(r["exp"], r["steps"], r["budget"], r["seed"])] = r
            rows = list(latest.values())
        (print_markdown if args.markdown else print_table)(rows)
        return
    cells = []
    for cell in args.cells.split(","):
        exp, _, steps = cell.partition(":")
        if exp not in GRID or not steps.isdigit() or int(steps) <= 0:
            sys.exit(f"error: grid cell {cell!r}: expected exp1:<steps> or exp2:<steps> with steps > 0")
        if exp == "exp2" and int(steps) % 500:
            sys.exit(f"error: grid cell {cell!r}: exp2 runs in episodes of 500 steps; "
                     f"steps must be a multiple of 500")
        cells.append((exp, int(steps)))
    budgets = args.budgets.split(",")
    for b in budgets:
        if b not in BUDGETS:
            sys.exit(f"error: budget {b!r}: expected one of {', '.join(BUDGETS)}")
    if not BIN.exists():
        sys.exit(f"error: {BIN} missing; build it with `cargo build --release -p causal-arm`")
    rows = []
    command = " ".join([sys.argv[0], "--cells", args.cells, "--budgets", args.budgets, "--seed", args.seed]
                       + (["--reexplain"] if args.reexplain else []))
    for exp, steps in cells:
        work = pathlib.Path(args.work) / f"{exp}_{steps}_seed{args.seed}"
        work.mkdir(parents=True, exist_ok=True)
        bag, truth, timings, results, seconds = prepare_bag(exp, steps, work, args.seed)
        seconds["data"] = timings["data"]
        for budget in budgets:
            cell_timings, cell_scores = model_cell(exp, bag, truth, budget, work, args.reuse_models,
                                                   args.reexplain)
            row = {"exp": exp, "steps": steps, "budget": budget, "seed": args.seed,
                   "scores": {**results, **{m: s for m, s in cell_scores.items()
                                            if m in (DEFAULT, "kernel+cai", "kernel/err", "cai/err")}},
                   "seconds": {**seconds, DEFAULT: cell_timings["train"] + cell_timings["explain"]},
                   "timings": {**timings, **cell_timings},
                   "command": command, "date": time.strftime("%Y-%m-%d %H:%M"),
                   "load": os.getloadavg()[0]}
            record_cell(record, row)
            rows.append(row)
            print_table([row])
            timings = {k: v for k, v in timings.items() if k in ("data", "anchors")}
    print()
    print_table(rows)


if __name__ == "__main__":
    main()
