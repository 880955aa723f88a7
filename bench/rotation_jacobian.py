#!/usr/bin/env python3
"""HHT's Newton matrix with the exact rotation blocks (`hht: {rotation_jacobian}`) on the ball chains.

    /usr/bin/python3 bench/rotation_jacobian.py --mbdae BUILD/mbdae [--repeats 3] [--n 10 100 1000]

For every chain (`bench/scenes/ball_chain.py`, 1 s), HHT fixed step h = 1e-3, 5e-4 and
2.5e-4 (N = 1000: 1e-3 only) and every setting -- the tree elimination and KLU, each
with its own defaults otherwise (the tree: refresh by cost 3 and the linear predictor;
KLU: cost 0 and the constant predictor) and with `--rotation-jacobian first-order` and
`exact` -- one `mbdae simulate` run, repeated `--repeats` times, the runs shuffled in
every repeat. Reported: the tip error at t = 1 s against the peers benchmark's reference
(`bench/results/peers/reference_chainN.json`), Newton iterations and factorisations per
step, the work per step in iterations (iterations + c x factorisations, c = 3 for the
tree, 5 for KLU, as `bench/jacobian_cost.py`), the solver's CPU time (median over the
repeats) and its ratio to the first-order matrix with the same solver. Writes
`bench/results/rotation_jacobian.md` and `.json`. The tests do not run it.
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import chain_runs  # noqa: E402

STEPS = {10: (1e-3, 5e-4, 2.5e-4), 100: (1e-3, 5e-4, 2.5e-4), 1000: (1e-3,)}
SETTINGS = [("tree", "first-order"), ("tree", "exact"), ("klu", "first-order"), ("klu", "exact")]
WORK_COST = {"tree": 3, "klu": 5}
ATTRS = ("linear_solver_used", "predictor_used", "rotation_jacobian_used")


def lines_of(out, repeats):
    """The results file's lines from write's dict."""
    lines = ["# HHT's Newton matrix with the exact rotation blocks on the ball chains", "",
             "`/usr/bin/python3 bench/rotation_jacobian.py --mbdae BUILD/mbdae --repeats %d` on %s, "
             "load average %.1f before and %.1f after. 1 s of each chain, HHT fixed step (alpha = "
             "-0.1, equilibrium form, modified), Newton threshold 1e-12; the tree with its defaults "
             "(refresh by cost 3, linear predictor), KLU with its own (cost 0, constant predictor); "
             "rotation blocks: `--rotation-jacobian`; work: iterations + c x factorisations per step "
             "with c = 3 (tree) or 5 (klu); error: the tip at t = 1 s against "
             "`bench/results/peers/reference_chainN.json`; time: the solver's CPU time, median of "
             "the repeats; ratios: against the first-order matrix with the same solver."
             % (repeats, out["date"], out["load_before"], out["load_after"]), ""]
    used = (("predictor_used", "predictor"), ("rotation_jacobian_used", "rotation blocks"))
    return lines + chain_runs.option_table(out["rows"], "rotation_jacobian", "first-order", used, WORK_COST)


def main():
    a = chain_runs.parse_args(__doc__, STEPS)
    runs_of = [(n, h, solver, rot) for n in a.n for h in STEPS[n] for solver, rot in SETTINGS]
    rows, load_before = chain_runs.hht_study(
        a, runs_of, lambda s: ["--linear-solver", s[2], "--rotation-jacobian", s[3]], ATTRS,
        lambda s: "N = %d, h = %g, %s, %s" % s, ("n", "h", "solver", "rotation_jacobian"))
    chain_runs.write(a.results, "rotation_jacobian", load_before, rows, lambda out: lines_of(out, a.repeats))


if __name__ == "__main__":
    main()
