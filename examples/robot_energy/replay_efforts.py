"""Open-loop replay of the drive torques of the quintic motion.

The arm of quintic.yaml is driven along the quintic rest-to-rest motion by three motion
joints; their efforts (/joints/driveK/effort, the motor torques) are the torques a
controller would feed forward. This script takes the efforts of one run, puts them as
cubic splines through every output row into the torque-driven arm of arm.yaml, runs that
arm open-loop with IDA at a tight tolerance and reports how far its joint angles drift
from the quintic motion (the closed form of quintic.yaml's motion joints). The arm is
unstable open-loop (gravity), so an error in the torques grows along the motion: the
drift measures how trustworthy the efforts of the rows are.

Sources of the efforts compared, each with output rows every 10 ms (quintic.yaml's
output step) and every 1 ms:
  - IDA rtol 1e-8, atol 1e-10, rows `integrator` (IDA's own multipliers) and `solved`
    (the acceleration-level equations at each row's t, q, v: the default);
  - HHT h = 1e-3, alpha = -0.1, rows `integrator` and `solved`;
  - the kinematic analysis (the motion solved from the constraints alone: the floor set
    by the replay itself, i.e. the spline interpolation and the replay's tolerance).

Run from the repository's root after `bash scripts/build.sh`:
  PYTHONPATH=build/python /usr/bin/python3 examples/robot_energy/replay_efforts.py \
      [--mbdae build/mbdae] [--out examples/robot_energy/replay_efforts.md]
"""
import argparse
import os
import subprocess
import sys
import tempfile

import h5py
import numpy as np

import mbdae

HERE = os.path.dirname(os.path.abspath(__file__))
QUINTIC = os.path.join(HERE, "quintic.yaml")
ARM = os.path.join(HERE, "arm.yaml")
# quintic.yaml's parameters (the motion's end points and duration)
Q0 = np.array([0.0, 0.3, -1.2])
QT = np.array([1.5, 0.9, -0.3])
T = 1.0
OUTPUT_STEPS = (1e-2, 1e-3)  # the rows the splines pass through

RUNS = [
    ("IDA rtol 1e-8, atol 1e-10", "integrator",
     ["--integrator", "ida", "--rtol", "1e-8", "--atol", "1e-10"]),
    ("IDA rtol 1e-8, atol 1e-10", "solved",
     ["--integrator", "ida", "--rtol", "1e-8", "--atol", "1e-10"]),
    ("HHT h = 1e-3, alpha = -0.1", "integrator", ["--integrator", "hht"]),
    ("HHT h = 1e-3, alpha = -0.1", "solved", ["--integrator", "hht"]),
    ("kinematic analysis", "solved", ["--integrator", "kinematic"]),
]


def quintic(t):
    s = t / T
    return Q0 + (QT - Q0) * (10 * s**3 - 15 * s**4 + 6 * s**5)[:, None]


def efforts(mbdae_bin, extra, rows, step, folder):
    out = os.path.join(folder, "efforts.h5")
    subprocess.run([mbdae_bin, "simulate", QUINTIC, "-o", out, "--output-step", str(step),
                    "--output-accelerations", rows, "--quiet", *extra], check=True)
    with h5py.File(out, "r") as f:
        t = f["time"][:]
        tau = np.stack([f["joints/drive%d/effort" % k][:] for k in (1, 2, 3)], axis=1)
    return t, tau


def replay(t, tau):
    with mbdae.Model(ARM) as m:
        for k in range(3):
            m.splines["tau%d" % (k + 1)] = (t, tau[:, k])
        m.options["integrator"] = "ida"
        m.options["ida.rtol"] = 1e-11
        m.options["ida.atol"] = 1e-13
        m.options["output_step"] = 0.01
        m.solve()
        q = np.stack([m.outputs.measure("q%d" % k) for k in (1, 2, 3)], axis=1)
        return m.outputs.time, q


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--mbdae", default=os.path.join("build", "mbdae"))
    ap.add_argument("--out", default=os.path.join(HERE, "replay_efforts.md"))
    args = ap.parse_args()
    lines = ["# Open-loop replay of the quintic motion's drive torques", "",
             "Produced by `examples/robot_energy/replay_efforts.py` (its docstring says how). "
             "Efforts of the rows (every 10 ms or 1 ms) of `quintic.yaml`, as cubic splines into the torque-driven "
             "`arm.yaml`, run open-loop with IDA rtol 1e-11, atol 1e-13; drift = the largest "
             "|q_K - q_K,quintic| over the rows every 10 ms of [0, 1] s.", "",
             "| efforts from | rows | row step [s] | drift base [rad] | shoulder [rad] | elbow [rad] | angles at 1 s: largest error [rad] |",
             "| --- | --- | --- | --- | --- | --- | --- |"]
    with tempfile.TemporaryDirectory() as folder:
        for step in OUTPUT_STEPS:
            for name, rows, extra in RUNS:
                t, tau = efforts(args.mbdae, extra, rows, step, folder)
                tr, q = replay(t, tau)
                err = np.abs(q - quintic(tr))
                drift = err.max(axis=0)
                line = "| %s | `%s` | %g | %.1e | %.1e | %.1e | %.1e |" % (
                    name, rows, step, drift[0], drift[1], drift[2], err[-1].max())
                print(line, flush=True)
                lines.append(line)
    with open(args.out, "w") as f:
        f.write("\n".join(lines) + "\n")
    print("wrote", os.path.relpath(args.out), file=sys.stderr)


if __name__ == "__main__":
    main()
