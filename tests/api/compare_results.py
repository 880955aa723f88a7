"""mbdae_write_results against `mbdae simulate`: the same datasets with the same values
(bitwise) and the same attributes, except the run's wall and CPU times.

Usage: compare_results.py MBDAE API_WRITE_RESULTS WORKDIR MODEL_DIR FREEDYN_MODEL
"""
import os
import subprocess
import sys

import h5py
import numpy as np

# Attributes that measure the run, not its results.
TIMES = {"wall_time", "solver_cpu_time"}


def datasets(f):
    out = {}
    f.visititems(lambda name, obj: out.__setitem__(name, obj[()])
                 if isinstance(obj, h5py.Dataset) else None)
    return out


def compare(program_file, api_file):
    problems = []
    with h5py.File(program_file, "r") as p, h5py.File(api_file, "r") as a:
        dp, da = datasets(p), datasets(a)
        if sorted(dp) != sorted(da):
            problems.append(f"datasets differ: {sorted(set(dp) ^ set(da))}")
        for name in sorted(set(dp) & set(da)):
            x, y = dp[name], da[name]
            if x.shape != y.shape or x.dtype != y.dtype:
                problems.append(f"{name}: shape/type {x.shape} {x.dtype} vs {y.shape} {y.dtype}")
            elif x.dtype.kind == "f":
                # Bitwise, NaN included.
                if x.tobytes() != y.tobytes():
                    diff = np.nanmax(np.abs(x - y)) if x.size else 0
                    problems.append(f"{name}: values differ (max {diff:g})")
            elif not np.array_equal(x, y):
                problems.append(f"{name}: values differ")
        attrs_p, attrs_a = dict(p.attrs), dict(a.attrs)
        if sorted(attrs_p) != sorted(attrs_a):
            problems.append(f"attributes differ: {sorted(set(attrs_p) ^ set(attrs_a))}")
        for name in sorted(set(attrs_p) & set(attrs_a)):
            if name in TIMES:
                continue
            x, y = attrs_p[name], attrs_a[name]
            if not np.array_equal(np.asarray(x), np.asarray(y)):
                problems.append(f"attribute {name}: {x!r} vs {y!r}")
        rows = p["time"].shape[0]
    return problems, rows, len(dp), len(attrs_p)


def main():
    mbdae, writer, workdir, model_dir, freedyn = sys.argv[1:6]
    os.makedirs(workdir, exist_ok=True)
    cases = [
        # model, program options, API options
        (os.path.join(model_dir, "slider_crank.yaml"), ["--integrator", "hht"], ["integrator=hht"]),
        (os.path.join(model_dir, "slider_crank.yaml"),
         ["--integrator", "ida", "--t-end", "0.3"], ["integrator=ida", "t_end=0.3"]),
        (os.path.join(model_dir, "spline_force.yaml"), ["--integrator", "ida"], ["integrator=ida"]),
        (freedyn, [], []),
    ]
    failed = False
    for k, (model, cli, api) in enumerate(cases):
        for steps in (False, True):
            tag = f"case{k}{'_steps' if steps else ''}"
            program_file = os.path.join(workdir, tag + "_program.h5")
            api_file = os.path.join(workdir, tag + "_api.h5")
            # The program writes the `model` attribute as the path it was given: give both
            # the same path.
            subprocess.run([mbdae, "simulate", model, "-q", "-o", program_file] + cli, check=True)
            subprocess.run([writer, model, api_file] + (["--steps"] if steps else []) + api,
                           check=True)
            problems, rows, nd, na = compare(program_file, api_file)
            label = f"{os.path.basename(model)} {' '.join(cli)}{' (stepped)' if steps else ''}"
            if problems:
                failed = True
                print(f"FAIL {label}:")
                for p in problems:
                    print("   ", p)
            else:
                print(f"ok   {label}: {nd} datasets ({rows} rows) bitwise equal, "
                      f"{na} attributes equal (times aside)")
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
