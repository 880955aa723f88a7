#!/usr/bin/env python3
"""The linear solvers of HHT and IDA (klu, tree) side by side on issue 12's ball chains.

    /usr/bin/python3 bench/linear_solver.py --mbdae BUILD/mbdae [--repeats 3] [--n 10 100 1000]

For every chain (`bench/scenes/ball_chain.py`, 1 s), integrator setting and linear solver
(`--linear-solver klu|tree`, `docs/hht.md`, "Linear solver"; HHT with KLU's refresh rules
and predictor, `--jacobian-cost 0 --predictor constant`, for both) one `mbdae simulate` run,
repeated `--repeats` times with the runs shuffled in every repeat (so that the two solvers
of a setting alternate over the invocation): HHT fixed h = 1e-3 and 2.5e-4, IDA rtol =
atol 1e-6 and 1e-8 (N = 1000: HHT h = 1e-3 and IDA 1e-6 only). Reported: the tip error at
t = 1 s against the peers benchmark's reference (`bench/results/peers/reference_chainN.json`),
steps, Newton iterations, factorisations, the solver CPU time (median over the repeats)
and its ratio tree / klu, and the linear solver that ran. Writes
`bench/results/linear_solver.md` and `.json`. The tests do not run it.
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import chain_runs  # noqa: E402

SETTINGS = {
    10: [("hht", 1e-3), ("hht", 2.5e-4), ("ida", 1e-6), ("ida", 1e-8)],
    100: [("hht", 1e-3), ("hht", 2.5e-4), ("ida", 1e-6), ("ida", 1e-8)],
    1000: [("hht", 1e-3), ("ida", 1e-6)],
}
SOLVERS = ("klu", "tree")


def options(integrator, value, solver):
    o = ["--integrator", integrator, "--linear-solver", solver]
    # HHT with KLU's refresh rules and predictor for both solvers (the tree's own defaults:
    # bench/jacobian_cost.py, bench/predictor.py), so that only the linear algebra differs.
    return o + (["--fixed-step", "--step", repr(value), "--jacobian-cost", "0", "--predictor", "constant"]
                if integrator == "hht" else ["--rtol", repr(value), "--atol", repr(value)])


def main():
    a = chain_runs.parse_args(__doc__, SETTINGS)
    refs = chain_runs.references(a.n)
    runs_of = [(n, integ, value, solver) for n in a.n for integ, value in SETTINGS[n] for solver in SOLVERS]
    load_before = os.getloadavg()[0]
    runs = chain_runs.run_shuffled(
        a.n, runs_of, a.repeats,
        lambda model, s, out: chain_runs.simulate(a.mbdae, model, s[0], options(*s[1:]), out,
                                                  ("linear_solver_used", "klu_fallbacks")),
        lambda s: "N = %d, %s %g, %s" % s)
    rows = []
    for s in runs_of:
        n, integ, value, solver = s
        row = {"n": n, "integrator": integ, "setting": value, "solver": solver}
        row.update(chain_runs.summary(runs[s], refs[n], ("linear_solver_used", "klu_fallbacks")))
        if "linear_solver_used" in row:
            row["used"] = row.pop("linear_solver_used")
            row["fallbacks"] = row.pop("klu_fallbacks")
        rows.append(row)

    def lines_of(out):
        lines = ["# The linear solvers of HHT and IDA on the ball chains", "",
                 "`/usr/bin/python3 bench/linear_solver.py --mbdae BUILD/mbdae --repeats %d` on %s, load "
                 "average %.1f before and %.1f after. 1 s of each chain; HHT fixed step (alpha = -0.1, "
                 "equilibrium form, modified), IDA rtol = atol; error: the tip at t = 1 s against "
                 "`bench/results/peers/reference_chainN.json`; time: the solver's CPU time, median of "
                 "the repeats; ratio: tree / klu of the same setting."
                 % (a.repeats, out["date"], load_before, out["load_after"]), "",
                 "| N | integrator | setting | solver | ran | tip error [m] | steps | Newton iterations "
                 "| factorisations | solver CPU [s] | tree / klu |",
                 "| ---: | --- | ---: | --- | --- | ---: | ---: | ---: | ---: | ---: | ---: |"]
        klu = {(r["n"], r["integrator"], r["setting"]): r for r in rows
               if r["solver"] == "klu" and "solver_time" in r}
        for r in rows:
            what = "h = %g" % r["setting"] if r["integrator"] == "hht" else "rtol %g" % r["setting"]
            if "solver_time" not in r:
                lines.append("| %d | %s | %s | %s | failed | | | | | | |" % (r["n"], r["integrator"], what, r["solver"]))
                continue
            k = klu.get((r["n"], r["integrator"], r["setting"]))
            ratio = "%.2f" % (r["solver_time"] / k["solver_time"]) if k and r["solver"] == "tree" else ""
            lines.append("| %d | %s | %s | %s | %s | %.3g | %d | %d | %d | %.3g | %s |" % (
                r["n"], r["integrator"], what, r["solver"], r["used"], r["error"], r["steps"], r["newton"],
                r["factorizations"], r["solver_time"], ratio))
        return lines

    chain_runs.write(a.results, "linear_solver", load_before, rows, lines_of)


if __name__ == "__main__":
    main()
