#!/usr/bin/env python3
"""HHT's refresh of the Newton matrix by cost (`hht: {jacobian_cost}`) on the ball chains.

    /usr/bin/python3 bench/jacobian_cost.py --mbdae BUILD/mbdae [--repeats 3] [--n 10 100 1000]

For every chain (`bench/scenes/ball_chain.py`, 1 s), HHT fixed step h = 1e-3 and 2.5e-4
(N = 1000: 1e-3 only) and every setting -- the tree elimination with `--jacobian-cost`
0 (the rate and age rules alone), 2, 3 (auto, the tree's default) and 4, and KLU with 0
(its default) and 5 -- one `mbdae simulate` run, repeated `--repeats` times, the runs
shuffled in every repeat. Reported: the tip error at t = 1 s against the peers
benchmark's reference (`bench/results/peers/reference_chainN.json`), Newton iterations
and factorisations per step, the work per step in iterations (iterations + c x
factorisations with c = 3 for the tree, 5 for KLU: what the cost measures), the solver's
CPU time (median over the repeats) and its ratio to cost 0 with the same solver. The
predictor is the constant one throughout (`--predictor constant`; the tree's default, the
linear one: bench/predictor.py), so that only the cost differs. Writes
`bench/results/jacobian_cost.md` and `.json`. The tests do not run it.
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import chain_runs  # noqa: E402

STEPS = {10: (1e-3, 2.5e-4), 100: (1e-3, 2.5e-4), 1000: (1e-3,)}
SETTINGS = [("tree", 0), ("tree", 2), ("tree", 3), ("tree", 4), ("klu", 0), ("klu", 5)]
WORK_COST = {"tree": 3, "klu": 5}


def main():
    a = chain_runs.parse_args(__doc__, STEPS)
    runs_of = [(n, h, solver, cost) for n in a.n for h in STEPS[n] for solver, cost in SETTINGS]
    rows, load_before = chain_runs.hht_study(
        a, runs_of,
        lambda s: ["--linear-solver", s[2], "--jacobian-cost", str(s[3]), "--predictor", "constant"],
        ("linear_solver_used", "jacobian_cost_used"), lambda s: "N = %d, h = %g, %s, cost %g" % s,
        ("n", "h", "solver", "jacobian_cost"))

    def lines_of(out):
        lines = ["# HHT's refresh of the Newton matrix by cost on the ball chains", "",
                 "`/usr/bin/python3 bench/jacobian_cost.py --mbdae BUILD/mbdae --repeats %d` on %s, load "
                 "average %.1f before and %.1f after. 1 s of each chain, HHT fixed step (alpha = -0.1, "
                 "equilibrium form, modified), Newton threshold 1e-12; cost: `--jacobian-cost` (0: the "
                 "rate and age rules alone; 3 is the tree's default, 0 KLU's); work: iterations + c x "
                 "factorisations per step with c = 3 (tree) or 5 (klu); error: the tip at t = 1 s against "
                 "`bench/results/peers/reference_chainN.json`; time: the solver's CPU time, median of "
                 "the repeats; ratio: against cost 0 with the same solver."
                 % (a.repeats, out["date"], load_before, out["load_after"]), "",
                 "| N | h | solver | cost | tip error [m] | steps | iterations / step "
                 "| factorisations / step | work / step | solver CPU [s] | ratio |",
                 "| ---: | ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
        base = {(r["n"], r["h"], r["solver"]): r for r in rows if r["jacobian_cost"] == 0 and "solver_time" in r}
        for r in rows:
            if "solver_time" not in r:
                lines.append("| %d | %g | %s | %g | failed | | | | | | |" % (r["n"], r["h"], r["solver"], r["jacobian_cost"]))
                continue
            b = base.get((r["n"], r["h"], r["solver"]))
            it, fa = r["newton"] / r["steps"], r["factorizations"] / r["steps"]
            lines.append("| %d | %g | %s | %g | %.4g | %d | %.2f | %.3f | %.2f | %.3g | %s |" % (
                r["n"], r["h"], r["linear_solver_used"], r["jacobian_cost"], r["error"], r["steps"], it, fa,
                it + WORK_COST[r["solver"]] * fa, r["solver_time"],
                "%.2f" % (r["solver_time"] / b["solver_time"]) if b else ""))
        return lines

    chain_runs.write(a.results, "jacobian_cost", load_before, rows, lines_of)


if __name__ == "__main__":
    main()
