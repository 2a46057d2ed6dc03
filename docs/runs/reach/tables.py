#!/usr/bin/env python3
"""Tables of the reach / place runs (issue 17) from their report.json files.

usage: tables.py exp2 RUNS_DIR | mpc RUNS_DIR | place RUNS_DIR"""

import json
import pathlib
import re
import statistics
import sys


def load(path):
    return json.loads(pathlib.Path(path).read_text())


def rate(log):
    found = re.findall(r"\((\d+)/s, ETA 0 s\)", pathlib.Path(log).read_text(errors="replace"))
    return found[-1] if found else "-"


def row(r):
    m = r["summary"]
    q = " / ".join(f"{x:.4f}" for x in m["final_error_p10_p50_p90"])
    return f"{100 * m['success_1cm']:.0f} % | {100 * m['success_5mm']:.0f} % | {m['median_steps_to_1cm'] if m['median_steps_to_1cm'] is not None else '-'} | {q}"


def ms_per_decision(r):
    log = (r.get("controller") or {}).get("log")
    return f"{1e3 * log['decision_seconds'] / log['decisions']:.2f}" if log else "-"


def reach_table(root, controllers, seeds):
    root = pathlib.Path(root)
    print("| seed | controller | within 1 cm | within 5 mm | median steps to 1 cm | final error p10/p50/p90 (m) | "
          "DDS steps/s | ms per decision DDS / in process | DDS = in process |")
    print("|---|---|---|---|---|---|---|---|---|")
    for s in seeds:
        for c in controllers:
            dds, local = root / f"{c}_s{s}", root / f"{c}_s{s}_proc"
            a, b = load(dds / "report.json"), load(local / "report.json")
            same = "yes" if a["episodes"] == b["episodes"] else "NO"
            print(f"| {s} | {c} | {row(a)} | {rate(str(dds) + '.log')} | {ms_per_decision(a)} / {ms_per_decision(b)} | {same} |")


def accuracy_vs_success(report):
    """Median FM prediction error of the targets reached within 5 mm and of the others."""
    errors = report["controller"]["log"]["prediction_error_per_target"]
    ok = [e for e, ep in zip(errors, report["episodes"]) if e is not None and ep["within_5mm_at"] is not None]
    bad = [e for e, ep in zip(errors, report["episodes"]) if e is not None and ep["within_5mm_at"] is None]
    med = lambda v: f"{1e3 * statistics.median(v):.1f} mm (n={len(v)})" if v else "- (n=0)"
    return med(ok), med(bad)


def main():
    what, root = sys.argv[1], pathlib.Path(sys.argv[2])
    if what == "exp2":
        reach_table(root, ["im", "fm-mpc", "jacobian", "random"], [1, 2, 3])
        print()
        for s in (1, 2, 3):
            im, jac = (load(root / f"{c}_s{s}" / "report.json")["summary"]["success_1cm"] for c in ("im", "jacobian"))
            mpc = load(root / f"fm-mpc_s{s}" / "report.json")["summary"]["success_1cm"]
            print(f"seed {s}: within 1 cm, IM / Jacobian = {im / jac:.2f}, FM-MPC / Jacobian = {mpc / jac:.2f} (target >= 0.90)")
    elif what == "mpc":
        print("| run | within 1 cm | within 5 mm | median steps to 1 cm | final error p10/p50/p90 (m) | ms per decision | "
              "median FM prediction error: reached 5 mm / not |")
        print("|---|---|---|---|---|---|---|")
        for d in sorted(root.glob("mpc_*")):
            if not (d / "report.json").exists():
                continue
            r = load(d / "report.json")
            ok, bad = accuracy_vs_success(r)
            print(f"| {d.name} ({r['over']}, horizon {r['controller']['cem']['horizon']}) | {row(r)} | {ms_per_decision(r)} | {ok} / {bad} |")
    elif what == "place":
        print("| seed | trials | within 3 cm | within 1 cm | cube held | final distance p10/p50/p90 (m) | median steps | "
              "ms per decision | DDS = in process |")
        print("|---|---|---|---|---|---|---|---|---|")
        for d in sorted(root.glob("place_s*")):
            if not d.is_dir() or d.name.endswith("_proc"):
                continue
            r = load(d / "report.json")
            local = d.with_name(d.name + "_proc") / "report.json"
            same = ("yes" if load(local)["trials"] == r["trials"] else "NO") if local.exists() else "-"
            m = r["summary"]
            q = " / ".join(f"{x:.4f}" for x in m["final_distance_p10_p50_p90"])
            steps = statistics.median(t["steps"] for t in r["trials"])
            log = r["planner"]["log"]
            ms = 1e3 * log["decision_seconds"] / log["decisions"]
            print(f"| {d.name[7:]} | {m['trials']} | {100 * m['placed_3cm']:.0f} % | {100 * m['placed_1cm']:.0f} % | "
                  f"{100 * m['held']:.0f} % | {q} | {steps:.0f} | {ms:.2f} | {same} |")
    else:
        sys.exit(__doc__)


if __name__ == "__main__":
    main()
