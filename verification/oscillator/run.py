#!/usr/bin/env python3
"""Acceptance 2: a single-mass oscillator whose spring and damper are a force
expression over a position measure and a velocity measure (oscillator.yaml) follows the
closed-form damped response to 1e-8 relative with IDA; the FreeDyn file
examples/freedyn/oscillator.fds (the same oscillator, written with PARVAL/MEAVAL) gives
the same rows as its YAML twin examples/freedyn/oscillator.yaml and the same response.

Closed form (underdamped, m u'' + d u' + k u = 0, u = x - L, u(0) = u0, u'(0) = v0):
  u = exp(-s t) (u0 cos(wd t) + (v0 + s u0)/wd sin(wd t)),  s = d/(2m), wd = sqrt(k/m - s^2).
Writes results.md (here, or in $MBDAE_VERIFICATION_OUT); exits 1 if a requirement fails.
"""
import argparse
import math
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.environ.get("MBDAE_VERIFICATION_OUT") or HERE
os.makedirs(OUT, exist_ok=True)
sys.path.insert(0, os.path.dirname(HERE))
import mbdae_run as mr  # noqa: E402

REPO = os.path.dirname(os.path.dirname(HERE))
FREEDYN = os.path.join(REPO, "examples", "freedyn")
IDA = ["--integrator", "ida", "--rtol", "1e-11", "--atol", "1e-13"]


def exact(t, m, k, d, u0, v0):
    s = d / (2 * m)
    wd = math.sqrt(k / m - s * s)
    return np.exp(-s * t) * (u0 * np.cos(wd * t) + (v0 + s * u0) / wd * np.sin(wd * t))


def relative_error(x, ref):
    return float(np.max(np.abs(x - ref))) / float(np.max(np.abs(ref)))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    mr.add_mbdae_argument(ap)
    args = ap.parse_args()
    runner = mr.Runner(mr.find_mbdae(args.mbdae), args.keep)
    checks = []

    # (a) the YAML model of this folder
    path, _ = runner.simulate(os.path.join(HERE, "oscillator.yaml"), IDA, "osc")
    r = mr.Results(path)
    t = r.time
    x = r["/measures/x"] - 0.2
    ref = exact(t, 1.5, 40.0, 0.8, 0.05, 0.5)
    err_a = relative_error(x, ref)
    checks.append(("oscillator.yaml (IDA rtol 1e-11): max abs(u - exact) / max abs(exact) = %.3e <= 1e-8" % err_a,
                   err_a <= 1e-8))

    # (b) the FreeDyn file and its YAML twin: same rows, same closed form (x offset at t = 0)
    fa, _ = runner.simulate(os.path.join(FREEDYN, "oscillator.fds"), IDA, "fds")
    fb, _ = runner.simulate(os.path.join(FREEDYN, "oscillator.yaml"), IDA, "fdsyaml")
    a, b = mr.Results(fa), mr.Results(fb)
    diff = max(float(np.max(np.abs(a[k] - b[k]))) for k in ("/q", "/v", "/measures/x", "/measures/v"))
    checks.append((".fds vs its YAML twin: max abs difference of q, v, measures = %.1e <= 1e-12" % diff,
                   diff <= 1e-12))
    err_b = relative_error(a["/measures/x"], exact(a.time, 1.5, 40.0, 0.8, 0.0, 0.5))
    checks.append(("oscillator.fds: max abs(x - exact) / max abs(exact) = %.3e <= 1e-8" % err_b, err_b <= 1e-8))

    md = ["# Single-mass oscillator with a force expression over measures: results\n",
          "Produced by `verification/oscillator/run.py` (IDA, rtol 1e-11, atol 1e-13, 3 s, 301 rows).\n",]
    return mr.finish_checks(runner, checks, md, OUT)


if __name__ == "__main__":
    sys.exit(main())
