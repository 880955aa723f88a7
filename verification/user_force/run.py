#!/usr/bin/env python3
"""Acceptance 6: the example user-force library, loaded by a model, reproduces the same
spring-damper built in, to 1e-11.

user.yaml names the library relative to itself (libmbdae_example_user_force.so); this
script copies user.yaml into the output folder and puts a link to the built library
(--library, the CMake target mbdae_example_user_force) next to it under that name, then
simulates user.yaml and its built-in twin builtin.yaml with the same fixed-step HHT and
compares the /q and /v rows (to 1e-11, relative to max(1, max |x|): round-off can change
where a Newton iteration stops, and it stops within 1e-12 of the solution in every step);
with IDA, whose
adaptive steps follow round-off differences, to the integration tolerance.
Writes results.md (here, or in $MBDAE_VERIFICATION_OUT); exits 1 if a requirement fails.
"""
import argparse
import os
import shutil
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.environ.get("MBDAE_VERIFICATION_OUT") or HERE
os.makedirs(OUT, exist_ok=True)
sys.path.insert(0, os.path.dirname(HERE))
import mbdae_run as mr  # noqa: E402

LIBRARY_NAME = "libmbdae_example_user_force.so"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    mr.add_mbdae_argument(ap)
    ap.add_argument("--library", required=True, help="the built example user-force library")
    args = ap.parse_args()
    runner = mr.Runner(mr.find_mbdae(args.mbdae), args.keep)

    # The model next to (a link to) the library, in the output folder.
    work = os.path.join(OUT, "model")
    os.makedirs(work, exist_ok=True)
    shutil.copyfile(os.path.join(HERE, "user.yaml"), os.path.join(work, "user.yaml"))
    link = os.path.join(work, LIBRARY_NAME)
    if os.path.lexists(link):
        os.remove(link)
    os.symlink(os.path.abspath(args.library), link)

    checks = []
    # HHT with a fixed step: the same steps, so the two runs agree to round-off.
    pu, _ = runner.simulate(os.path.join(work, "user.yaml"), [], "user")
    pb, _ = runner.simulate(os.path.join(HERE, "builtin.yaml"), [], "builtin")
    u, b = mr.Results(pu), mr.Results(pb)
    same_rows = u["/q"].shape == b["/q"].shape
    travel = float(np.max(np.abs(b["/q"] - b["/q"][0])))
    for key in ("/q", "/v"):
        diff = float(np.max(np.abs(u[key] - b[key]))) if same_rows else float("inf")
        scale = max(1.0, float(np.max(np.abs(b[key]))))
        checks.append(("HHT fixed step 1e-3, %d rows: max abs difference of %s = %.1e <= 1e-11 * %.2f "
                       "(the body moves %.2f)" % (u["/q"].shape[0], key, diff, scale, travel),
                       same_rows and diff <= 1e-11 * scale and travel > 0.1))
    # IDA chooses its steps from error estimates that differ by round-off between the runs:
    # the two agree to the integration tolerance, not to round-off.
    ida = ["--integrator", "ida", "--rtol", "1e-10", "--atol", "1e-12"]
    pu, _ = runner.simulate(os.path.join(work, "user.yaml"), ida, "user")
    pb, _ = runner.simulate(os.path.join(HERE, "builtin.yaml"), ida, "builtin")
    u, b = mr.Results(pu), mr.Results(pb)
    diff = float(np.max(np.abs(u["/q"] - b["/q"])))
    checks.append(("IDA rtol 1e-10 (adaptive steps): max abs difference of /q = %.1e <= 1e-7" % diff, diff <= 1e-7))

    md = ["# User-force library vs the built-in spring_damper: results\n",
          "Produced by `verification/user_force/run.py` (user.yaml with the example library "
          "examples/user_force/linear_spring_damper.c vs builtin.yaml, 2 s, 201 rows).\n",]
    return mr.finish_checks(runner, checks, md, OUT)


if __name__ == "__main__":
    sys.exit(main())
