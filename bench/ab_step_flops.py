"""Two builds' bench_step_flops side by side: runs the two programs alternately, REPEATS
times each on the same ball chains, and prints per benchmark the smallest and the median
CPU time of each and their ratio (B / A). On a machine shared with other jobs the
interference only adds time, so the minima are the steadier comparison; the medians show
how much the runs moved.

    /usr/bin/python3 bench/ab_step_flops.py A/bench/peers/bench_step_flops \\
        B/bench/peers/bench_step_flops [--n 100] [--repeats 8] \\
        [--filter 'BM_HhtStep/100/12/1/|BM_KluRefactorSolve/100']

The chain models come from bench/scenes/ball_chain.py (the ones bench/peers/run.py uses).
Used for bench/README.md, "The Newton iteration's own cost".
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("a", help="the first build's bench_step_flops")
    ap.add_argument("b", help="the second build's bench_step_flops")
    ap.add_argument("--n", type=int, nargs="+", default=[100], help="chain sizes")
    ap.add_argument("--repeats", type=int, default=8, help="runs of each program")
    ap.add_argument("--filter", default="BM_HhtStep/.*/12/1/|BM_HhtRefresh/.*/1/|"
                    "BM_HhtStep/.*/12/0/|BM_KluRefactorSolve|BM_TreeLu",
                    help="Google Benchmark filter")
    args = ap.parse_args()
    for exe in (args.a, args.b):
        if not os.access(exe, os.X_OK):
            sys.exit("ab_step_flops: %s is not an executable" % exe)
    times = {}  # (name, which) -> CPU times
    with tempfile.TemporaryDirectory() as tmp:
        models = []
        for n in args.n:
            path = os.path.join(tmp, "chain%d.yaml" % n)
            subprocess.run([sys.executable, os.path.join(ROOT, "bench", "scenes", "ball_chain.py"),
                            str(n), "-o", path], check=True)
            models += ["--model", "%d=%s" % (n, path)]
        out = os.path.join(tmp, "out.json")
        for rep in range(args.repeats):
            for which, exe in (("A", args.a), ("B", args.b)):
                subprocess.run([exe] + models + ["--benchmark_filter=" + args.filter,
                                                 "--benchmark_out=" + out,
                                                 "--benchmark_out_format=json"],
                               check=True, stdout=subprocess.DEVNULL)
                with open(out) as f:
                    for r in json.load(f)["benchmarks"]:
                        times.setdefault((r["name"], which), []).append(r["cpu_time"])
            print("repeat %d of %d done" % (rep + 1, args.repeats), file=sys.stderr)
    print("| benchmark | A min | A median | B min | B median | B / A (minima) |")
    print("| --- | ---: | ---: | ---: | ---: | ---: |")
    for name in sorted({n for n, _ in times}):
        a, b = times.get((name, "A")), times.get((name, "B"))
        if not (a and b):
            continue
        print("| %s | %.1f | %.1f | %.1f | %.1f | %.2f |" % (
            name, min(a), statistics.median(a), min(b), statistics.median(b), min(b) / min(a)))


if __name__ == "__main__":
    main()
