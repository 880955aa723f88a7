#!/usr/bin/python3
"""Make the "measurement" of the identification example: measurement.csv.

    /usr/bin/python3 examples/identification/make_measurement.py [--sigma 0.01] [--seed 1]
        [--k 1] [--c 1]

Simulates model.yaml at the true parameter values (--k, --c: default k = 1 N/m and
c = 1 N s/m, SUNDIALS' values; model.yaml itself holds the wrong starting guess) with
`build/mbdae simulate --set k=.. --set c=..` (HHT, h = 1e-3, rows every 0.01 s), reads
the slider position xs from the results file (h5py), samples it every 0.05 s over
[0, 10] s (201 samples), adds Gaussian noise of standard deviation --sigma (default
0.01 m, about 1.6 % of the slider's 0.63 m swing) drawn by numpy's default_rng(--seed)
(default seed 1), and writes measurement.csv next to model.yaml: a header line, comment
lines with the settings and the truth, then t, s_meas (the noisy sample: the spline
s_meas of model.yaml reads these two columns) and s_true (the noise-free sample, for
reference only).

The model reads measurement.csv itself (the spline), so the simulation runs on a copy of
model.yaml in a temporary folder with a placeholder data file: the signal xs does not
depend on the spline (only the objective does).
"""
import argparse
import os
import shutil
import subprocess
import sys
import tempfile

import h5py
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))


def simulate_signal(mbdae, model, extra=()):
    """(t, xs, parameters) of `mbdae simulate` on a copy of `model` with a placeholder
    measurement.csv (two points), in a temporary folder."""
    with tempfile.TemporaryDirectory(prefix="mbdae_ident_") as tmp:
        copy = os.path.join(tmp, "model.yaml")
        shutil.copyfile(model, copy)
        with open(os.path.join(tmp, "measurement.csv"), "w") as f:
            f.write("t,s_meas\n0,0\n10,0\n")
        results = os.path.join(tmp, "truth.h5")
        subprocess.run([mbdae, "simulate", copy, "-o", results, "--quiet", *extra],
                       check=True)
        with h5py.File(results, "r") as h5:
            if h5.attrs["status"] != "done":
                sys.exit(f"make_measurement: the run did not finish: {h5.attrs['status']}")
            t = np.array(h5["time"])
            xs = np.array(h5["measures/xs"])
            params = {name[len("parameter."):]: float(value)
                      for name, value in h5.attrs.items() if name.startswith("parameter.")}
    return t, xs, params


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--mbdae", default=os.path.join(ROOT, "build", "mbdae"))
    ap.add_argument("--model", default=os.path.join(HERE, "model.yaml"))
    ap.add_argument("--k", type=float, default=1.0, help="true stiffness, N/m (default 1)")
    ap.add_argument("--c", type=float, default=1.0, help="true damping, N s/m (default 1)")
    ap.add_argument("--sigma", type=float, default=0.01, help="noise standard deviation, m")
    ap.add_argument("--seed", type=int, default=1, help="seed of numpy's default_rng")
    ap.add_argument("--every", type=int, default=5,
                    help="take every N-th row of the results (rows every 0.01 s; default 5)")
    ap.add_argument("--out", default=os.path.join(HERE, "measurement.csv"))
    args = ap.parse_args()

    t, xs, params = simulate_signal(args.mbdae, args.model,
                                    ["--set", f"k={args.k!r}", "--set", f"c={args.c!r}"])
    t_s, s_true = t[::args.every], xs[::args.every]
    rng = np.random.default_rng(args.seed)
    s_meas = s_true + args.sigma * rng.standard_normal(t_s.size)

    with open(args.out, "w") as f:
        f.write("t,s_meas,s_true\n")
        f.write(f"# slider position xs of model.yaml at k = {params['k']!r}, "
                f"c = {params['c']!r} (build/mbdae simulate, HHT h = 1e-3)\n")
        f.write(f"# sampled every {t_s[1] - t_s[0]:.3g} s, {t_s.size} samples; s_meas = s_true"
                f" + Gaussian noise from numpy default_rng(seed).standard_normal\n")
        f.write(f"# noise: sigma = {args.sigma!r} m, seed = {args.seed}\n")
        f.write(f"# truth: k = {params['k']!r}, c = {params['c']!r}\n")
        for ti, mi, si in zip(t_s, s_meas, s_true):
            f.write(f"{ti:.10g},{mi:.17g},{si:.17g}\n")
    noise = s_meas - s_true
    print(f"wrote {os.path.relpath(args.out)}: {t_s.size} samples over [{t_s[0]:g}, {t_s[-1]:g}] s,"
          f" k = {params['k']:g}, c = {params['c']:g}, sigma = {args.sigma:g} m"
          f" (sample std of the noise {noise.std(ddof=1):.4g} m, swing of xs"
          f" {xs.max() - xs.min():.4g} m)")


if __name__ == "__main__":
    main()
