#!/usr/bin/env python3
"""Acceptance 4: a gear pair (gear.yaml) keeps its ratio to 1e-10 over a 10 s run.

The gear joint's equation is (phi2 - phi2_0) - r (phi1 - phi1_0) = 0 with r = -2 and
phi_0 the angles of the model file's initial state. The angles are read from the
results file (unwrapped across +-pi by the program) and the check is
    max_t |(phi2 - phi2_0) - r (phi1 - phi1_0)| <= 1e-10 rad,
run with IDA and with HHT. Also reported: the total turns of each wheel.
Writes results.md (here, or in $MBDAE_VERIFICATION_OUT); exits 1 if a requirement fails.
"""
import argparse
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.environ.get("MBDAE_VERIFICATION_OUT") or HERE
os.makedirs(OUT, exist_ok=True)
sys.path.insert(0, os.path.dirname(HERE))
import mbdae_run as mr  # noqa: E402

RATIO = -2.0
J1, J2 = 0.02, 0.005


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    mr.add_mbdae_argument(ap)
    args = ap.parse_args()
    runner = mr.Runner(mr.find_mbdae(args.mbdae), args.keep)
    checks, rows = [], []
    for name, extra in (("IDA rtol 1e-10", []),
                        ("HHT h = 1e-3", ["--integrator", "hht", "--step", "1e-3"])):
        path, _ = runner.simulate(os.path.join(HERE, "gear.yaml"), extra, "gear")
        r = mr.Results(path)
        t = r.time
        p1, p2 = r["/measures/phi1"], r["/measures/phi2"]
        err = float(np.max(np.abs((p2 - 0.4) - RATIO * (p1 - 0.0))))
        turns1, turns2 = (p1[-1] - p1[0]) / (2 * np.pi), (p2[-1] - p2[0]) / (2 * np.pi)
        rows.append("| %s | %.2f | %.2f | %.3e |" % (name, turns1, turns2, err))
        checks.append(("%s: max abs((phi2 - phi2_0) - r (phi1 - phi1_0)) = %.3e <= 1e-10" % (name, err),
                       err <= 1e-10))
        if t[-1] < 10 - 1e-9 or abs(turns1) < 2:
            checks.append(("%s: the run reaches 10 s and wheel 1 turns at least twice" % name, False))
    md = ["# Gear pair: results\n",
          "Produced by `verification/gear/run.py` (10 s, ratio -2, wheel 1 driven by 0.05 sin(t) N m).\n",
          "| integrator | turns of wheel 1 | turns of wheel 2 | max abs ratio error (rad) |",
          "|---|---|---|---|"] + rows + [""]
    return mr.finish_checks(runner, checks, md, OUT)


if __name__ == "__main__":
    sys.exit(main())
