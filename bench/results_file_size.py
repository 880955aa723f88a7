#!/usr/bin/env python3
"""Size and time of a short run's results file for large chains (issue 12, output phase).

    /usr/bin/python3 bench/results_file_size.py [--mbdae BUILD/mbdae] [--n 1000 10000]

For each N: the ball chain of bench/scenes/ball_chain.py with t_end = output_step = 1e-3
s (2 rows), `mbdae simulate` (its default integrator), the results file's size and the process'
wall and CPU time. Written to bench/results/results_file_size.md. A run of a commit
before 090fbe8 (chunks of about 8 KiB per dataset whatever the run) with the same command
gives the comparison.
"""
import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, os.path.join(HERE, "scenes"))
import ball_chain  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mbdae", default=os.path.join(ROOT, "build", "mbdae"))
    ap.add_argument("--n", type=int, nargs="+", default=[1000, 10000])
    ap.add_argument("--out", default=os.path.join(HERE, "results", "results_file_size.md"))
    a = ap.parse_args()
    commit = subprocess.run(["git", "-C", ROOT, "rev-parse", "--short", "HEAD"],
                            capture_output=True, text=True).stdout.strip()
    rows = []
    with tempfile.TemporaryDirectory(prefix="mbdae_size_") as tmp:
        for n in a.n:
            model = os.path.join(tmp, "chain%d.yaml" % n)
            ball_chain.write_chain(model, n, t_end=1e-3, output_step=1e-3)
            out = os.path.join(tmp, "chain%d.h5" % n)
            before = resource.getrusage(resource.RUSAGE_CHILDREN)
            t0 = time.perf_counter()
            subprocess.run([a.mbdae, "simulate", model, "-o", out,
                            "--quiet"], check=True)
            wall = time.perf_counter() - t0
            after = resource.getrusage(resource.RUSAGE_CHILDREN)
            cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
            size = os.path.getsize(out)
            rows.append((n, size, wall, cpu))
            print("N = %d: %.1f MB, %.2f s wall, %.2f s CPU" % (n, size / 1e6, wall, cpu))
    load = os.getloadavg()
    with open(a.out, "w") as f:
        f.write("# Results file of a 2-row run of the ball chain\n\n")
        f.write("`/usr/bin/python3 bench/results_file_size.py` at %s; load average %.1f, %.1f, "
                "%.1f.\n\n" % (commit, *load))
        f.write("| N | file [MB] | wall [s] | CPU [s] |\n| ---: | ---: | ---: | ---: |\n")
        for n, size, wall, cpu in rows:
            f.write("| %d | %.1f | %.2f | %.2f |\n" % (n, size / 1e6, wall, cpu))
    print("wrote", os.path.relpath(a.out, ROOT))


if __name__ == "__main__":
    main()
