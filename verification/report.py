#!/usr/bin/env python3
"""Builds the verification report: runs every verification study and paper reproduction
in its full form, one after another (so the CPU times of the work-precision studies are
measured without competition). Each script refreshes the outputs in its own folder
(results.md, figures as PNG, data as CSV, summary.json), and the report

    verification/REPORT.md   links to them (the committed report), or, with --out DIR,
    DIR/report.md            a self-contained copy: DIR/<item>/ holds each item's files.

Exit status: the number of items with a failed check or a failed run (0: all passed).

Usage: python3 verification/report.py [--mbdae build/mbdae] [--out DIR] [--only NAME ...]
(--only reruns the named items; the others keep the outputs of the last full build.)
"""
import argparse
import csv
import datetime
import glob
import json
import math
import os
import shutil
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import mbdae_run as mr  # noqa: E402

REPO = mr.REPO

# (section, name, script relative to the repository, extra arguments)
ITEMS = [
    ("IFToMM group A", "pendulum", "verification/pendulum/run.py", []),
    ("IFToMM group A", "nfourbar", "verification/nfourbar/run.py", []),
    ("IFToMM group A", "andrews", "verification/andrews/run.py", []),
    ("IFToMM group A", "bricard", "verification/bricard/run.py", []),
    ("IFToMM group A", "flyball", "verification/flyball/run.py", []),
    ("Hard cases", "heavy_top", "verification/heavy_top/run.py", []),
    ("Hard cases", "long_run", "verification/long_run/run.py", []),
    ("Hard cases", "stiff_spring", "verification/stiff_spring/run.py", []),
    ("Hard cases", "redundant", "verification/redundant/run.py", []),
    ("Hard cases", "singular", "verification/singular/run.py", []),
    ("Hard cases", "discontinuous", "verification/discontinuous/run.py", []),
    ("Convergence orders", "orders", "verification/orders/run.py", []),
    ("Elements", "free_body", "verification/free_body/run.py", []),
    ("Elements", "oscillator", "verification/oscillator/run.py", []),
    ("Elements", "crank_motion", "verification/crank_motion/run.py", []),
    ("Elements", "gear", "verification/gear/run.py", []),
    ("Elements", "user_force", "verification/user_force/run.py", ["--library", "{library}"]),
    ("Published results", "sherif2019-modified-hht", "papers/sherif2019-modified-hht/run.py", []),
    ("Published results", "negrut2007-hht", "papers/negrut2007-hht/run.py", []),
    ("Published results", "andrews-testset", "papers/andrews-testset/run.py", []),
    ("Published results", "bryson1963-state-constraint", "papers/bryson1963-state-constraint/run.py", []),
]
ERROR_LEVELS = [1e-2, 1e-3, 1e-4, 1e-6, 1e-8]


def item_dir(item, out_root, copy):
    """(folder holding the item's outputs, its path relative to the report)."""
    if copy:
        return os.path.join(out_root, item[1]), item[1]
    folder = os.path.dirname(os.path.join(REPO, item[2]))
    return folder, os.path.relpath(folder, out_root)


def run_item(item, mbdae, library, out_root, python, copy):
    section, name, script, extra = item
    folder = os.path.dirname(os.path.join(REPO, script))
    args = [python, os.path.join(REPO, script), "--mbdae", mbdae]
    args += [a.format(library=library) for a in extra]
    env = dict(os.environ, MPLBACKEND="Agg")
    env.pop("MBDAE_VERIFICATION_OUT", None)  # the script refreshes its own folder
    start = time.time()
    proc = subprocess.run(args, cwd=REPO, env=env, stdout=subprocess.PIPE,
                          stderr=subprocess.STDOUT, text=True)
    seconds = time.time() - start
    dest, _ = item_dir(item, out_root, copy)
    if copy:
        os.makedirs(dest, exist_ok=True)
        with open(os.path.join(dest, "log.txt"), "w") as f:
            f.write(proc.stdout)
    if proc.returncode != 0:
        print("\n" + "\n".join(proc.stdout.splitlines()[-15:]))
    summary = {}
    path = os.path.join(folder, "summary.json")
    if os.path.isfile(path) and os.path.getmtime(path) >= start - 1:
        with open(path) as f:
            summary = json.load(f)
    if copy:
        for f in ["results.md", "summary.json"] + summary.get("figures", []) + summary.get("csv", []):
            src = os.path.join(folder, f)
            if os.path.isfile(src):
                shutil.copy(src, os.path.join(dest, f))
    return {"item": item, "section": section, "name": name, "script": script, "rc": proc.returncode,
            "seconds": seconds, "summary": summary, "log": proc.stdout}


def read_wp(path):
    rows = []
    with open(path) as f:
        for r in csv.DictReader(f):
            try:
                r["cpu_time"] = float(r["cpu_time"])
                r["error"] = float(r["error"])
            except (KeyError, ValueError):
                continue
            if r.get("status", "done") == "done" and math.isfinite(r["error"]):
                rows.append(r)
    return rows


def winners_table(results, out_root, copy):
    """For each work-precision study and error level: the cheapest run (CPU time) of each
    integrator kind that reaches the level, and the winner."""
    lines = ["| problem | error <= | " + " | ".join(["hht-fixed", "hht-adaptive", "ida"])
             + " | fastest |", "|---|---|---|---|---|---|"]
    for res in results:
        wp = res["summary"].get("work_precision")
        if not wp or res["section"] == "Published results":  # the studies only, once each
            continue
        path = os.path.join(item_dir(res["item"], out_root, copy)[0], wp)
        if not os.path.isfile(path):
            continue
        rows = read_wp(path)
        problems = sorted(set(r["problem"] for r in rows))
        for prob in problems:
            pr = [r for r in rows if r["problem"] == prob]
            for level in ERROR_LEVELS:
                best = {}
                for kind in ("hht-fixed", "hht-adaptive", "ida"):
                    ok = [r for r in pr if r["integrator"] == kind and r["error"] <= level]
                    if ok:
                        best[kind] = min(ok, key=lambda r: r["cpu_time"])
                if not best:
                    continue
                cells = []
                for kind in ("hht-fixed", "hht-adaptive", "ida"):
                    b = best.get(kind)
                    cells.append("%.3g s (%s)" % (b["cpu_time"], b["setting"]) if b else "not reached")
                win = min(best, key=lambda k: best[k]["cpu_time"])
                lines.append("| %s | %g | %s | **%s** |" % (prob, level, " | ".join(cells), win))
    return "\n".join(lines) + "\n"


def iftomm_table(results):
    rows = []
    for res in results:
        for r in res["summary"].get("iftomm", []):
            rows.append(r)
    rows.sort(key=lambda r: (r["problem"], r.get("cpu_time", 0)))
    lines = ["| problem | integrator | setting | quantity | error | tolerance | CPU [s] | within |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append("| %s | %s | %s | %s | %.2e | %g | %.3g | %s |" % (
            r["problem"], r["integrator"], r.get("setting", ""), r.get("quantity", ""),
            r["error"], r["tolerance"], r.get("cpu_time", float("nan")),
            "yes" if r["passed"] else "NO"))
    cheapest = {}
    for r in rows:
        if r["passed"] and (r["problem"] not in cheapest
                            or r["cpu_time"] < cheapest[r["problem"]]["cpu_time"]):
            cheapest[r["problem"]] = r
    problems = sorted(set(r["problem"] for r in rows))
    summary = ["| problem | meets 1e-3 | cheapest run that meets it |", "|---|---|---|"]
    for p in problems:
        c = cheapest.get(p)
        summary.append("| %s | %s | %s |" % (
            p, "yes" if c else "NO",
            "%s, %s: error %.1e, %.3g s CPU" % (c["integrator"], c.get("setting", ""), c["error"],
                                                 c["cpu_time"]) if c else "-"))
    return "\n".join(summary) + "\n\nAll runs:\n\n" + "\n".join(lines) + "\n", problems, cheapest


def demote_headings(text):
    out = []
    for line in text.splitlines():
        if line.startswith("#"):
            line = "###" + line
        out.append(line)
    return "\n".join(out)


def main():
    parser = argparse.ArgumentParser(description="Builds the verification report.")
    parser.add_argument("--mbdae", default=None, help="the program (default $MBDAE, else build/mbdae)")
    parser.add_argument("--library", default=None,
                        help="the example user-force library (default: next to the program, "
                             "examples/user_force/libmbdae_spring_damper.so)")
    parser.add_argument("--out", default=None,
                        help="write a self-contained copy of the report into this folder "
                             "(default: verification/REPORT.md, linking to the items' folders)")
    parser.add_argument("--only", nargs="*", default=None, help="run only these items")
    args = parser.parse_args()
    mbdae = mr.find_mbdae(args.mbdae)
    library = args.library or os.path.join(os.path.dirname(mbdae), "examples", "user_force",
                                           "libmbdae_spring_damper.so")
    python = sys.executable
    copy = args.out is not None
    out_root = os.path.abspath(args.out) if copy else HERE
    os.makedirs(out_root, exist_ok=True)
    report_path = os.path.join(out_root, "report.md" if copy else "REPORT.md")
    results = []
    t0 = time.time()
    for item in ITEMS:
        if args.only is not None and item[1] not in args.only:
            # Not rerun: the item's outputs of an earlier build of the report, if any.
            prev = os.path.join(item_dir(item, out_root, copy)[0], "summary.json")
            if os.path.isfile(prev):
                with open(prev) as f:
                    summary = json.load(f)
                results.append({"item": item, "section": item[0], "name": item[1], "script": item[2], "rc": 0,
                                "seconds": 0, "summary": summary, "log": "(not rerun)"})
            continue
        if not os.path.isfile(os.path.join(REPO, item[2])):
            print("%-26s missing (%s)" % (item[1], item[2]))
            results.append({"item": item, "section": item[0], "name": item[1], "script": item[2], "rc": -1,
                            "seconds": 0, "summary": {}, "log": "script missing"})
            continue
        print("%-26s ..." % item[1], end="", flush=True)
        res = run_item(item, mbdae, library, out_root, python, copy)
        checks = res["summary"].get("checks", [])
        passed = sum(1 for c in checks if c["passed"])
        print(" exit %d, checks %d/%d, %.0f s" % (res["rc"], passed, len(checks), res["seconds"]))
        results.append(res)
    total = time.time() - t0

    rerun = "all items" if args.only is None else "the items " + ", ".join(args.only) + \
        " (the others from the last full build)"
    md = ["# mbdae verification report\n",
          "Built by `python3 verification/report.py` on %s: %s, in %.1f minutes (wall time, "
          "one after another). CPU times are the program's `solver_cpu_time`: seconds in "
          "the integrator, without output; they come from one run on one machine and are "
          "comparable within this report only.\n" % (
              datetime.date.today().isoformat(), rerun, total / 60)]
    failed = 0
    md.append("## Summary\n")
    md.append("| section | item | checks passed | result | time [s] |\n|---|---|---|---|---|")
    for res in results:
        checks = res["summary"].get("checks", [])
        passed = sum(1 for c in checks if c["passed"])
        ok = res["rc"] == 0 and passed == len(checks) and checks
        failed += 0 if ok else 1
        md.append("| %s | [%s](#%s) | %d/%d%s | %s | %.0f |" % (
            res["section"], res["name"], res["name"].replace("_", "-").lower(), passed,
            len(checks), "" if res["rc"] == 0 else " (exit %d)" % res["rc"],
            res["summary"].get("headline", "").replace("|", "/"), res["seconds"]))
    md.append("")

    table, problems, cheapest = iftomm_table(results)
    md.append("## IFToMM group A: high-precision tolerance (1e-3)\n")
    md.append("Which integrator meets the published high-precision tolerance on each problem's "
              "quantity, and at what cost (the error is the largest deviation over the run from "
              "the reference each item's README states):\n")
    md.append(table)

    md.append("## Work-precision: which integrator wins where\n")
    md.append("For each work-precision study and error level, the least CPU time of each "
              "integrator among the runs of its sweep that reach the level (setting in brackets), "
              "and the fastest. The figures are in the items' sections.\n")
    md.append(winners_table(results, out_root, copy))

    section = None
    for res in results:
        if res["section"] != section:
            section = res["section"]
            md.append("## %s\n" % section)
        md.append("<a id=\"%s\"></a>\n### %s\n" % (res["name"].replace("_", "-").lower(),
                                                   res["summary"].get("title", res["name"])))
        md.append("Script: `%s` (README: `%s/README.md`).\n" % (
            res["script"], os.path.dirname(res["script"])))
        folder, link = item_dir(res["item"], out_root, copy)
        for fig in res["summary"].get("figures", []):
            md.append("![%s](%s/%s)\n" % (fig, link, fig))
        csvs = res["summary"].get("csv", [])
        if csvs:
            md.append("Data: " + ", ".join("[%s](%s/%s)" % (c, link, c) for c in csvs) + "\n")
        rpath = os.path.join(folder, "results.md")
        if os.path.isfile(rpath) and res["rc"] != -1:
            with open(rpath) as f:
                text = f.read()
            # Figures referenced by results.md sit in the item's folder.
            text = text.replace("](", "](%s/" % link).replace(
                "](%s/http" % link, "](http").replace("](%s/#" % link, "](#")
            md.append(demote_headings(text) + "\n")
        else:
            md.append("No results (%s).\n" % res["log"][-500:].replace("\n", " "))
    with open(report_path, "w") as f:
        f.write("\n".join(md) + "\n")
    print("report: %s (%d items, %d with failures, %.1f min)" % (
        os.path.relpath(report_path, REPO), len(results), failed, total / 60))
    return failed


if __name__ == "__main__":
    sys.exit(main())
