#!/usr/bin/env python3
"""HHT's Newton threshold against accuracy and time on issue 12's ball chains.

    /usr/bin/python3 bench/newton_tolerance.py --mbdae BUILD/mbdae [--repeats 3] [--linear-solver tree]

For every chain (N = 10, 100, 1000; `bench/scenes/ball_chain.py`, 1 s), fixed step h and
threshold (`--newton-tolerance`, 1e-12 the default ... 1e-8) one `mbdae simulate` run,
repeated `--repeats` times with the settings shuffled in every repeat (the runs of one
setting spread over the invocation); the tip error at t = 1 s against the peers
benchmark's reference (`bench/results/peers/reference_chainN.json`, Simbody RK-Merson at
accuracy 1e-12, 1e-11, 1e-9, checked there against RK-Feldberg and IDA), the Newton
iterations, factorisations and the solver CPU time (median over the repeats). Writes
`bench/results/newton_tolerance.md` and `.json`; with `--linear-solver tree` (the tree
elimination with its defaults: the refresh by cost and the linear predictor)
`newton_tolerance_tree.md` and `.json`. The tests do not run it.
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import chain_runs  # noqa: E402

TOLERANCES = (1e-12, 1e-11, 1e-10, 1e-9, 1e-8)
STEPS = {10: (1e-3, 2.5e-4), 100: (1e-3, 2.5e-4), 1000: (1e-3,)}


def main():
    a = chain_runs.parse_args(__doc__, STEPS, lambda ap: ap.add_argument(
        "--linear-solver", choices=("klu", "tree"), default="klu", help="HHT's linear solver (default klu)"))
    tree = a.linear_solver == "tree"
    refs = chain_runs.references(a.n)
    settings = [(n, h, tol) for n in a.n for h in STEPS[n] for tol in TOLERANCES]
    load_before = os.getloadavg()[0]
    runs = chain_runs.run_shuffled(
        a.n, settings, a.repeats,
        lambda model, s, out: chain_runs.simulate(
            a.mbdae, model, s[0], ["--integrator", "hht", "--fixed-step", "--step", repr(s[1]),
                                   "--newton-tolerance", repr(s[2]), "--linear-solver", a.linear_solver], out),
        lambda s: "N = %d, h = %g, newton_tolerance = %g" % s)
    rows = []
    for s in settings:
        n, h, tol = s
        row = {"n": n, "h": h, "newton_tolerance": tol}
        row.update(chain_runs.summary(runs[s], refs[n]))
        rows.append(row)

    def lines_of(out):
        lines = ["# HHT's Newton threshold on the ball chains", "",
                 "`/usr/bin/python3 bench/newton_tolerance.py --mbdae BUILD/mbdae --repeats %d%s` on %s, load "
                 "average %.1f before and %.1f after. Fixed-step HHT (alpha = -0.1, equilibrium form, "
                 "modified%s), 1 s; error: the tip at t = 1 s against `bench/results/peers/reference_chainN.json`; "
                 "time: the solver's CPU time, median of the repeats (the other numbers are the same in "
                 "every repeat); time ratio: against the default threshold 1e-12 of the same N and h."
                 % (a.repeats, " --linear-solver tree" if tree else "", out["date"], load_before,
                    out["load_after"], "; the tree elimination with its refresh by cost and linear "
                    "predictor" if tree else "; KLU"), "",
                 "| N | h | newton_tolerance | tip error [m] | error / default's | Newton iterations / step "
                 "| factorisations / step | solver CPU [s] | time / default's |",
                 "| ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
        base = {(r["n"], r["h"]): r for r in rows if r["newton_tolerance"] == 1e-12 and "error" in r}
        for r in rows:
            if "error" not in r:
                lines.append("| %d | %g | %g | failed | | | | | |" % (r["n"], r["h"], r["newton_tolerance"]))
                continue
            b = base.get((r["n"], r["h"]))
            lines.append("| %d | %g | %g | %.4g | %.3f | %.2f | %.3f | %.3g | %.2f |" % (
                r["n"], r["h"], r["newton_tolerance"], r["error"], r["error"] / b["error"] if b else float("nan"),
                r["newton"] / r["steps"], r["factorizations"] / r["steps"], r["solver_time"],
                r["solver_time"] / b["solver_time"] if b else float("nan")))
        return lines

    chain_runs.write(a.results, "newton_tolerance_tree" if tree else "newton_tolerance", load_before, rows,
                     lines_of)


if __name__ == "__main__":
    main()
