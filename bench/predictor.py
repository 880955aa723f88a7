#!/usr/bin/env python3
"""HHT's predictor of the Newton iteration (`hht: {predictor}`) on the ball chains.

    /usr/bin/python3 bench/predictor.py --mbdae BUILD/mbdae [--repeats 3] [--n 10 100 1000]

For every chain (`bench/scenes/ball_chain.py`, 1 s), HHT fixed step h = 1e-3 and 2.5e-4
(N = 1000: 1e-3 only) and every setting -- the tree elimination with its refresh by cost
(`--jacobian-cost auto`, 3) and KLU with its rules (`auto`, 0), each with `--predictor
constant` and `linear` -- one `mbdae simulate` run, repeated `--repeats` times, the runs
shuffled in every repeat. Reported: the tip error at t = 1 s against the peers
benchmark's reference (`bench/results/peers/reference_chainN.json`), Newton iterations
and factorisations per step, the work per step in iterations (iterations + c x
factorisations, c = 3 for the tree, 5 for KLU, as `bench/jacobian_cost.py`), the
solver's CPU time (median over the repeats) and its ratio to the constant predictor with
the same solver. Writes `bench/results/predictor.md` and `.json`. The tests do not run
it.
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import chain_runs  # noqa: E402

STEPS = {10: (1e-3, 2.5e-4), 100: (1e-3, 2.5e-4), 1000: (1e-3,)}
SETTINGS = [("tree", "constant"), ("tree", "linear"), ("klu", "constant"), ("klu", "linear")]
WORK_COST = {"tree": 3, "klu": 5}
ATTRS = ("linear_solver_used", "jacobian_cost_used", "predictor_used")


def lines_of(out, repeats):
    """The results file's lines from write's dict."""
    lines = ["# HHT's predictor of the Newton iteration on the ball chains", "",
             "`/usr/bin/python3 bench/predictor.py --mbdae BUILD/mbdae --repeats %d` on %s, load "
             "average %.1f before and %.1f after. 1 s of each chain, HHT fixed step (alpha = -0.1, "
             "equilibrium form, modified), Newton threshold 1e-12; the tree with its refresh by cost "
             "(3), KLU with its rules (cost 0); predictor: `--predictor`; work: iterations + c x "
             "factorisations per step with c = 3 (tree) or 5 (klu); error: the tip at t = 1 s against "
             "`bench/results/peers/reference_chainN.json`; time: the solver's CPU time, median of "
             "the repeats; ratio: against the constant predictor with the same solver."
             % (repeats, out["date"], out["load_before"], out["load_after"]), ""]
    used = (("predictor_used", "predictor"),)
    return lines + chain_runs.option_table(out["rows"], "predictor", "constant", used, WORK_COST)


def main():
    a = chain_runs.parse_args(__doc__, STEPS)
    runs_of = [(n, h, solver, pred) for n in a.n for h in STEPS[n] for solver, pred in SETTINGS]
    rows, load_before = chain_runs.hht_study(
        a, runs_of, lambda s: ["--linear-solver", s[2], "--predictor", s[3]], ATTRS,
        lambda s: "N = %d, h = %g, %s, %s" % s, ("n", "h", "solver", "predictor"))
    chain_runs.write(a.results, "predictor", load_before, rows, lambda out: lines_of(out, a.repeats))


if __name__ == "__main__":
    main()
