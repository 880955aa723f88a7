#!/usr/bin/env python3
"""Gradients on SUNDIALS' slider-crank (idasSlCrank): G = integral over [0, 10] s of the
kinetic energy, parameters k, c (and phi0, the initial crank angle, which positions every
body), with every method of `mbdae gradient` against the independent reference of
reference.py (reference.json).

1. The reference: recomputed (DOP853, rtol 1e-13) and equal to reference.json (1e-12).
2. Sweeps with `mbdae gradient slider_crank.yaml --objective G --wrt k,c[,phi0] --json`:
   HHT fixed step h = 4e-3 ... 1.25e-4 (alpha -0.1, modified scheme, equilibrium form),
   HHT adaptive tol = 1e-4 ... 1e-12, IDA rtol = 1e-6 ... 1e-11 (atol = rtol / 10; rtol
   1e-6 is about the example's own setting), each with --method adjoint and forward; fd at
   some points. Error = |dG/dp - reference| / |reference| per parameter.
Checks (the script exits 1 if one fails):
   a. every gradient computation finished;
   b. acceptance (the issue): at the tight end of each sweep (HHT h = 1.25e-4, HHT adaptive
      tol 1e-12, IDA rtol 1e-11) adjoint, forward and fd are within 1e-6 of the reference
      for dG/dk and dG/dc (fd: HHT the program's fd at relative step 1e-3; IDA the
      program's fd of runs at rtol 1e-12, extrapolated to step 0 as in d);
   c. HHT forward = adjoint on the same discretisation (every fixed and adaptive run of
      the sweeps): relative difference <= 1e-9;
   d. HHT adjoint = central differences of the same discrete runs: the program's fd at
      relative steps 5e-4 ... 8e-3, extrapolated to step 0 by weighted least squares in s^2
      and s^4 (a single step is truncation- or noise-limited near 1e-7), <= 1e-7 relative,
      with identical base runs; fixed h = 1e-3 and adaptive tol 1e-9 (fd replays the
      accepted steps), wrt k, c, phi0;
   e. gradients through an initial position set by a parameter: dG/dphi0 from HHT
      (adjoint, forward, h = 2.5e-4) and IDA (adjoint, forward, rtol 1e-10) within 1e-6 of
      the reference;
   f. IDA forward and adjoint (separate runs) agree to 1e3 rtol.
Also (no check): fd at the program's default step and the example's setting, and the
mechanism with a revolute wrist (3 redundant equations). Writes results.md, summary.json,
gradients.csv and convergence.png (gradient error against step and tolerance, one curve
per method and integrator).
--quick: HHT h = 1e-3, HHT adaptive tol 1e-9 and 1e-11, IDA rtol 1e-10, the same kinds of
checks at those settings (acceptance at h = 1e-3, tol 1e-11, rtol 1e-10, without IDA fd);
no figure. About 10 s of CPU.
"""
import argparse
import csv
import json
import os
import subprocess
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.environ.get("MBDAE_VERIFICATION_OUT") or HERE
os.makedirs(OUT, exist_ok=True)
sys.path.insert(0, os.path.dirname(HERE))
sys.path.insert(0, HERE)
import mbdae_run as mr  # noqa: E402
import reference as refmod  # noqa: E402

MODEL = os.path.join(HERE, "slider_crank.yaml")
OUTPUT_STEP = 0.1
ALPHA = -0.1
PARAMS = ("k", "c", "phi0")


class Case:
    def __init__(self, integrator, setting, x, method, args, wrt=("k", "c"), label=None):
        self.integrator, self.setting, self.x, self.method = integrator, setting, x, method
        self.args, self.wrt = list(args), tuple(wrt)
        self.label = label or integrator
        self.status, self.message = "failed", ""
        self.value = None
        self.grad = {}
        self.err = {}
        self.err_G = None
        self.cpu = self.gcpu = self.steps = self.runs = None
        self.fd_steps = None
        self.wall = None

    def key(self):
        return (self.integrator, self.setting, tuple(self.wrt))

    def max_err(self, params=("k", "c")):
        v = [self.err[p] for p in params if p in self.err]
        return max(v) if v else None


def hht_fixed(h):
    return ["--integrator", "hht", "--alpha", repr(ALPHA), "--step", repr(h), "--fixed-step"]


def hht_adaptive(tol):
    return ["--integrator", "hht", "--alpha", repr(ALPHA), "--adaptive", "--tolerance", repr(tol), "--step", "1e-3"]


def ida(rtol, atol=None):
    return ["--integrator", "ida", "--rtol", repr(rtol), "--atol", repr(atol if atol is not None else rtol / 10)]


def run_gradient(mbdae, case, ref, model=MODEL):
    cmd = [mbdae, "gradient", model, "--objective", "G", "--wrt", ",".join(case.wrt), "--method", case.method,
           "--json", "--quiet", "--output-step", repr(OUTPUT_STEP)] + case.args
    t0 = time.time()
    proc = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    case.wall = time.time() - t0
    text = proc.stdout.strip()
    data = None
    try:
        data = json.loads(text) if text else None
    except ValueError:
        data = None
    if data is None:
        lines = (proc.stderr.strip() or proc.stdout.strip() or "exit %d" % proc.returncode).splitlines()
        case.message = "exit %d: %s" % (proc.returncode, lines[0][:300])
        return
    if data.get("status", "done") != "done" or proc.returncode != 0:
        case.message = "exit %d: %s" % (proc.returncode, data.get("failure_reason", "status " + str(data.get("status"))))
        return
    try:
        g = data["objectives"]["G"]
        case.value = float(g["value"])
        case.grad = {p: float(g["gradient"][p]) for p in case.wrt}
    except (KeyError, TypeError, ValueError) as e:
        case.message = "unexpected JSON (%s): %s" % (e, text[:300])
        return
    case.err_G = abs(case.value - ref["G"]) / abs(ref["G"])
    case.err = {p: abs(case.grad[p] - ref["gradient"][p]) / abs(ref["gradient"][p]) for p in case.wrt}
    case.cpu = data.get("solver_cpu_time")
    case.gcpu = data.get("gradient_cpu_time")
    case.steps = data.get("forward_steps")
    case.runs = data.get("runs")
    case.fd_steps = data.get("fd_steps")
    case.status = "done"


def report_case(c):
    print("%-13s %-13s %-16s %s" % (c.integrator, c.setting, c.method + (
        " " + c.args[c.args.index("--fd-step") + 1] if "--fd-step" in c.args else ""), (
        "G err %.1e  dG/d(%s) err %s  cpu %s + %s s  steps %s" % (
            c.err_G, ",".join(c.wrt), " ".join("%.1e" % c.err[p] for p in c.wrt), fmt(c.cpu, "%.2f"),
            fmt(c.gcpu, "%.2f"), c.steps)) if c.status == "done" else "FAILED: " + c.message), flush=True)


def same_run(a, b):
    """the forward runs of two gradient computations are the same run: equal step counts, G to 1e-12"""
    return a.steps == b.steps and abs(a.value - b.value) <= 1e-12 * abs(b.value)


def method_label(c):
    if c.method == "fd":
        return "fd (step %s)" % (c.args[c.args.index("--fd-step") + 1] if "--fd-step" in c.args else "1e-5")
    if c.method == "fd-extrapolated":
        return "fd extrapolated to step 0"
    return c.method


def rel_diff(a, b, params):
    """max over params of |a - b| / |b| (None if either is missing)"""
    if a.status != "done" or b.status != "done":
        return None
    return max(abs(a.grad[p] - b.grad[p]) / abs(b.grad[p]) for p in params)


FD_STEPS = (5e-4, 1e-3, 2e-3, 4e-3, 8e-3)


def fd_extrapolated(mbdae, integrator, setting, x, args, wrt, ref, label):
    """Central differences of the same discrete runs (the program's fd at the relative steps
    FD_STEPS), extrapolated to step 0: weighted least squares of D(s) = D0 + C s^2 + E s^4
    with weights s (the runs' noise in G enters D(s) as noise / s). Returns a Case with
    method "fd-extrapolated" (grad = D0; .fit_scatter the weighted rms residual relative
    to D0) and the individual fd cases."""
    subs = []
    for st in FD_STEPS:
        c = Case(integrator, setting, x, "fd", args + ["--fd-step", repr(st)], wrt, label)
        run_gradient(mbdae, c, ref)
        subs.append(c)
    out = Case(integrator, setting, x, "fd-extrapolated", args, wrt, label)
    out.subs = subs
    bad = [c for c in subs if c.status != "done"]
    if bad:
        out.message = "fd at step %s: %s" % (bad[0].args[-1], bad[0].message)
        return out
    out.status, out.value = "done", subs[0].value
    out.scatter = {}
    for p in wrt:
        s_abs = np.array([c.fd_steps[p] for c in subs])
        d = np.array([c.grad[p] for c in subs])
        A = np.stack([np.ones_like(s_abs), s_abs**2, s_abs**4], axis=1) * s_abs[:, None]
        coef, *_ = np.linalg.lstsq(A, d * s_abs, rcond=None)
        out.grad[p] = float(coef[0])
        res = (A @ coef - d * s_abs) / s_abs
        out.scatter[p] = float(np.sqrt(np.mean(res**2)) / abs(coef[0]))
    out.err_G = abs(out.value - ref["G"]) / abs(ref["G"])
    out.err = {p: abs(out.grad[p] - ref["gradient"][p]) / abs(ref["gradient"][p]) for p in wrt}
    out.cpu = subs[0].cpu
    out.gcpu = sum(c.gcpu or 0.0 for c in subs)
    out.steps = subs[0].steps
    out.runs = sum(c.runs or 0 for c in subs)
    return out


def fmt(x, f="%.1e"):
    return "-" if x is None else f % x


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    mr.add_mbdae_argument(ap)
    ap.add_argument("--quick", action="store_true", help="a small subset (the test suite's)")
    args = ap.parse_args()
    mbdae = mr.find_mbdae(args.mbdae)
    runner = mr.Runner(mbdae, args.keep)
    t_start = time.time()
    checks = []
    md = ["# Slider-crank (SUNDIALS idasSlCrank): gradients, verification results\n",
          "Produced by `verification/slider_crank/run.py%s`; model `verification/slider_crank/slider_crank.yaml`; "
          "G = integral over [0, 10] s of the kinetic energy; every gradient run is `mbdae gradient slider_crank.yaml "
          "--objective G --wrt ... --method M --json --output-step %g` plus the integrator's options (HHT: "
          "alpha = %g, modified scheme, equilibrium form; IDA: atol = rtol / 10 unless stated).\n"
          % (" --quick" if args.quick else "", OUTPUT_STEP, ALPHA)]

    # 1. reference
    with open(os.path.join(HERE, "reference.json")) as f:
        ref = json.load(f)
    G_now, grad_now, _ = refmod.solve()
    dref = max([abs(G_now - ref["G"]) / abs(ref["G"])]
               + [abs(grad_now[p] - ref["gradient"][p]) / abs(ref["gradient"][p]) for p in PARAMS])
    checks.append(("reference recomputed (DOP853, rtol 1e-13) equals reference.json: %.1e relative (tolerance 1e-12)"
                   % dref, dref <= 1e-12))
    md.append("## 1. Reference\n")
    md.append("`reference.py`: the crank angle's Lagrange equation with forward sensitivities, scipy DOP853 at "
              "rtol 1e-13 (reference.json). G = %.15f, dG/dk = %.13f, dG/dc = %.13f, dG/dphi0 = %.12f. Its "
              "error estimate (change against rtol 1e-11): %.1e; against its own 4th-order central differences: "
              "%.1e. The SUNDIALS example prints G = %.16f (idasSlCrank_dns, IDAS rtol 1e-6): %.1e off; its "
              "forward-sensitivity gradient (3.3346e-01, -3.6375e-01): %.1e, %.1e off.\n"
              % (ref["G"], ref["gradient"]["k"], ref["gradient"]["c"], ref["gradient"]["phi0"],
                 max(ref["relative_change_vs_rtol_1e-11"].values()),
                 max(ref["central_differences_relative_difference"].values()),
                 ref["sundials"]["G"]["idasSlCrank_dns"], ref["sundials"]["relative_difference_G"]["idasSlCrank_dns"],
                 ref["sundials"]["relative_difference_gradient_k_c"]["forward"][0],
                 ref["sundials"]["relative_difference_gradient_k_c"]["forward"][1]))

    # 2. the runs
    cases = []
    if args.quick:
        steps, tols, rtols = [1e-3], [1e-9, 1e-11], [1e-10]
        h_tight, tol_tight, rtol_tight, rtol_fd = 1e-3, 1e-11, 1e-10, None
        h_fd, tol_fd, tol_fd_loose = 1e-3, 1e-9, None
        h_phi, rtol_phi = 1e-3, 1e-10
    else:
        steps = [4e-3, 2e-3, 1e-3, 5e-4, 2.5e-4, 1.25e-4]
        tols = [1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12]
        rtols = [1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11]
        h_tight, tol_tight, rtol_tight, rtol_fd = steps[-1], tols[-1], rtols[-1], 1e-12
        h_fd, tol_fd, tol_fd_loose = 1e-3, 1e-9, 1e-6
        h_phi, rtol_phi = 2.5e-4, 1e-10
    for h in steps:
        wrt = PARAMS if (h in (h_fd, h_phi) or args.quick) else ("k", "c")
        for m in ("adjoint", "forward"):
            cases.append(Case("hht", "h = %.4g" % h, h, m, hht_fixed(h), wrt, "HHT fixed step"))
    for tol in tols:
        wrt = PARAMS if (tol in (tol_fd, tol_fd_loose) or args.quick) else ("k", "c")
        for m in ("adjoint", "forward"):
            cases.append(Case("hht-adaptive", "tol = %.0e" % tol, tol, m, hht_adaptive(tol), wrt, "HHT adaptive"))
    for rtol in rtols:
        wrt = PARAMS if (rtol == rtol_phi or args.quick) else ("k", "c")
        for m in ("adjoint", "forward"):
            cases.append(Case("ida", "rtol = %.0e" % rtol, rtol, m, ida(rtol), wrt, "IDA"))
    # the program's fd at the tight settings (HHT: relative step 1e-3, whose truncation error
    # is about 1e-7 here and whose noise is below; IDA: tighter runs and step 1e-4)
    cases.append(Case("hht", "h = %.4g" % h_tight, h_tight, "fd", hht_fixed(h_tight) + ["--fd-step", "1e-3"],
                      ("k", "c"), "HHT fixed step"))
    cases.append(Case("hht-adaptive", "tol = %.0e" % tol_tight, tol_tight, "fd",
                      hht_adaptive(tol_tight) + ["--fd-step", "1e-3"], ("k", "c"), "HHT adaptive"))
    if rtol_fd is not None:
        cases.append(Case("ida", "rtol = %.0e" % rtol_fd, rtol_fd, "fd", ida(rtol_fd) + ["--fd-step", "1e-4"],
                          PARAMS, "IDA"))
        # the example's own setting and fd step (rtol 1e-6, atol 1e-7, dp = 1e-5)
        cases.append(Case("ida", "rtol = 1e-06", 1e-6, "fd", ida(1e-6) + ["--fd-step", "1e-5"], ("k", "c"), "IDA"))
    if tol_fd_loose is not None:
        # fd of an adaptive run at the program's default step, where the exact methods' forward run
        # and fd's base run use different Newton thresholds (see README)
        cases.append(Case("hht-adaptive", "tol = %.0e" % tol_fd_loose, tol_fd_loose, "fd",
                          hht_adaptive(tol_fd_loose), PARAMS, "HHT adaptive"))
        cases.append(Case("hht", "h = %.4g" % h_fd, h_fd, "fd", hht_fixed(h_fd), PARAMS, "HHT fixed step"))
    for c in cases:
        run_gradient(mbdae, c, ref)
        report_case(c)
    # central differences of the same discrete runs, extrapolated to step 0
    extra = [fd_extrapolated(mbdae, "hht", "h = %.4g" % h_fd, h_fd, hht_fixed(h_fd), PARAMS, ref, "HHT fixed step"),
             fd_extrapolated(mbdae, "hht-adaptive", "tol = %.0e" % tol_fd, tol_fd, hht_adaptive(tol_fd), PARAMS, ref,
                             "HHT adaptive")]
    if rtol_fd is not None:
        # whole IDA runs carry their global error (about 30 rtol here) as noise between nearby
        # parameters: one fd step is either truncation- or noise-limited at 1e-6
        extra.append(fd_extrapolated(mbdae, "ida", "rtol = %.0e" % rtol_fd, rtol_fd, ida(rtol_fd), PARAMS, ref, "IDA"))
    for c in extra:
        for sub in getattr(c, "subs", []):
            report_case(sub)
        report_case(c)
    cases += extra
    cases += [sub for c in extra for sub in getattr(c, "subs", [])]

    def find(integrator, x, method, need=None, fd_step=None):
        for c in cases:
            if c.integrator == integrator and c.x == x and c.method == method and (need is None or need in c.wrt) \
                    and (fd_step is None or ("--fd-step" in c.args and c.args[c.args.index("--fd-step") + 1] == fd_step)
                         or (fd_step == "default" and "--fd-step" not in c.args)):
                return c
        return None

    failed = [c for c in cases if c.status != "done"]
    checks.append(("every gradient run finished (%d gradient computations, %d failed%s)" % (
        len(cases), len(failed), "".join("; %s %s %s: %s" % (c.integrator, c.setting, c.method, c.message[:160])
                                         for c in failed[:6])), not failed))

    # b. acceptance: every method within 1e-6 of the reference at tight settings
    tight = [(find("hht", h_tight, m, fd_step="1e-3" if m == "fd" else None), "HHT h = %.4g" % h_tight)
             for m in ("adjoint", "forward", "fd")]
    tight += [(find("hht-adaptive", tol_tight, m, fd_step="1e-3" if m == "fd" else None),
               "HHT adaptive tol %.0e" % tol_tight) for m in ("adjoint", "forward", "fd")]
    tight += [(find("ida", rtol_tight, m), "IDA rtol %.0e" % rtol_tight) for m in ("adjoint", "forward")]
    if rtol_fd is not None:
        tight.append((find("ida", rtol_fd, "fd-extrapolated"), "IDA rtol %.0e" % rtol_fd))
    by_integ = {}
    for (c, where), group in zip(tight, ["HHT fixed step"] * 3 + ["HHT adaptive"] * 3 + ["IDA"] * 3):
        e = c.max_err() if c is not None and c.status == "done" else None
        by_integ.setdefault(group, []).append((where, method_label(c) if c else "?", e))
    for integ, rows_ in by_integ.items():
        checks.append(("acceptance, %s: every method within 1e-6 of the reference (largest relative error of dG/dk, "
                       "dG/dc) at the tight end: %s" % (integ, "; ".join("%s %s %s" % (w, m, fmt(e))
                                                                          for w, m, e in rows_)),
                       all(e is not None and e <= 1e-6 for _, _, e in rows_)))

    # c. HHT forward = adjoint on the same discretisation
    for integ, name in (("hht", "fixed step"), ("hht-adaptive", "adaptive")):
        diffs = []
        for c in cases:
            if c.integrator == integ and c.method == "adjoint":
                f = find(integ, c.x, "forward")
                d = rel_diff(f, c, c.wrt) if f is not None else None
                if d is not None:
                    diffs.append(d)
        worst = max(diffs) if diffs else None
        checks.append(("HHT %s: forward = adjoint on the same run, largest relative difference over %d runs %s "
                       "(tolerance 1e-9)" % (name, len(diffs), fmt(worst)), worst is not None and worst <= 1e-9))

    # d. HHT adjoint = fd of the same discrete runs
    for integ, x, name in (("hht", h_fd, "fixed step h = %.4g" % h_fd),
                           ("hht-adaptive", tol_fd, "adaptive tol %.0e (fd replays the accepted steps)" % tol_fd)):
        a, f = find(integ, x, "adjoint", "phi0"), find(integ, x, "fd-extrapolated")
        d = {p: abs(a.grad[p] - f.grad[p]) / abs(f.grad[p]) for p in PARAMS} if (
            a and f and a.status == f.status == "done") else None
        same = (a and f and a.status == f.status == "done" and same_run(a, f))
        checks.append(("HHT %s: adjoint = central differences of the same discrete runs (the program's fd at "
                       "relative steps %s, extrapolated to 0; scatter of the fit %s): %s (tolerance 1e-7); base "
                       "runs identical (step count, G to 1e-12): %s"
                       % (name, ", ".join("%g" % s_ for s_ in FD_STEPS),
                          ", ".join("%.0e" % v for v in f.scatter.values()) if d else "-",
                          ", ".join("%s %.1e" % (p, d[p]) for p in PARAMS) if d else "no result",
                          "yes" if same else "NO"),
                       d is not None and max(d.values()) <= 1e-7 and bool(same)))

    # e. phi0 through the initial state
    phi_rows, phi_ok = [], True
    for integ, x, where in (("hht", h_phi, "HHT h = %.4g" % h_phi), ("ida", rtol_phi, "IDA rtol %.0e" % rtol_phi)):
        for m in ("adjoint", "forward"):
            c = find(integ, x, m, "phi0")
            e = c.err.get("phi0") if c is not None and c.status == "done" else None
            phi_ok &= e is not None and e <= 1e-6
            phi_rows.append("%s %s %s" % (where, m, fmt(e)))
    checks.append(("dG/dphi0 (phi0 sets the initial position of every body) within 1e-6 of the reference: %s"
                   % "; ".join(phi_rows), phi_ok))

    # f. IDA forward vs adjoint
    ida_rows, ida_ok = [], True
    for rtol in rtols:
        a, f = find("ida", rtol, "adjoint"), find("ida", rtol, "forward")
        d = rel_diff(a, f, ("k", "c")) if a and f else None
        ida_ok &= d is not None and d <= 1e3 * rtol
        ida_rows.append("%.0e: %s" % (rtol, fmt(d)))
    checks.append(("IDA forward vs adjoint (separate runs) within 1e3 rtol: %s" % ", ".join(ida_rows), ida_ok))

    # g. (full run only, no check) the same mechanism with a revolute wrist: 3 redundant equations
    redundant_rows = []
    if not args.quick:
        with open(MODEL) as fm:
            text = fm.read()
        old = "{name: wrist, type: generic, i: rod.cm, j: slider.cm, lock: [x, y]}"
        if old in text:
            rmodel = os.path.join(runner.dir, "slider_crank_revolute_wrist.yaml")
            with open(rmodel, "w") as fm:
                fm.write(text.replace(old, "{name: wrist, type: revolute, i: rod.cm, j: slider.cm}"))
            for label, x, a_ in (("IDA", 1e-6, ida(1e-6)), ("IDA", 1e-8, ida(1e-8)), ("IDA", 1e-10, ida(1e-10)),
                                 ("HHT fixed step", 1e-3, hht_fixed(1e-3))):
                for m in ("adjoint", "forward"):
                    c = Case("redundant", "%s %g" % (label, x), x, m, a_, PARAMS, label)
                    run_gradient(mbdae, c, ref, rmodel)
                    report_case(c)
                    base = find("ida" if label == "IDA" else "hht", x, m)
                    d = rel_diff(c, base, tuple(p for p in c.wrt if base and p in base.wrt)) if base else None
                    redundant_rows.append([label, "%g" % x, m, "done" if c.status == "done" else
                                           "FAILED: " + c.message[:160],
                                           fmt(c.max_err(PARAMS)) if c.status == "done" else "-", fmt(d)])

    # tables
    md.append("## 2. Gradients against the reference\n")
    md.append("Relative errors |dG/dp - ref| / |ref|; G's own relative error; CPU of the forward run and of the "
              "gradient beyond it (`solver_cpu_time`, `gradient_cpu_time`); steps of the forward run; fd: whole "
              "runs (1 + 2 per parameter). Data: `gradients.csv`.\n")
    rows = []
    for c in cases:
        if c.status == "done":
            rows.append([c.label, c.setting, method_label(c), "%.10f" % c.value, fmt(c.err_G)] +
                        ["%.12f" % c.grad[p] if p in c.grad else "" for p in PARAMS] +
                        [fmt(c.err[p]) if p in c.err else "" for p in PARAMS] +
                        [fmt(c.cpu, "%.2f"), fmt(c.gcpu, "%.2f"), c.steps, c.runs])
        else:
            rows.append([c.label, c.setting, method_label(c), "failed: " + c.message[:200]] + [""] * 11)
    md.append(mr.markdown_table(["integrator", "setting", "method", "G", "err G", "dG/dk", "dG/dc", "dG/dphi0",
                                 "err k", "err c", "err phi0", "CPU fwd [s]", "CPU grad [s]", "steps", "runs"], rows))

    md.append("\n## 3. Agreement between the methods\n")
    rows = []
    for c in cases:
        if c.method != "adjoint" or c.status != "done":
            continue
        others = [o for o in cases if o is not c and o.integrator == c.integrator and o.x == c.x and
                  o.method != "adjoint" and o.status == "done"]
        for o in others:
            common = tuple(p for p in c.wrt if p in o.wrt)
            rows.append([c.label, c.setting, "adjoint vs " + method_label(o), ", ".join(
                "%s %.1e" % (p, abs(c.grad[p] - o.grad[p]) / abs(o.grad[p])) for p in common),
                "same" if same_run(o, c) else
                "differ (G %.1e, %s vs %s steps)" % (abs(o.value - c.value) / abs(c.value), c.steps, o.steps)])
    md.append("Relative difference |adjoint - other| / |other| per parameter. HHT: forward and fd are of the same "
              "discrete runs (fd of an adaptive run replays the accepted steps of its own base run); IDA: the forward "
              "sensitivities, the adjoint's checkpointed run and fd's runs are separate adaptive runs, so their "
              "differences are of the size of the tolerance. The last column compares the base runs (G and step "
              "count of the forward run).\n")
    md.append(mr.markdown_table(["integrator", "setting", "comparison", "relative difference", "base runs"], rows))

    if redundant_rows:
        md.append("\n## 4. The same mechanism with a revolute wrist (3 redundant equations; no check)\n")
        md.append("`slider_crank.yaml` with the wrist as a `revolute` joint instead of the generic x-y pin: the "
                  "assembly sets aside 3 redundant equations (the planar loop closed with spatial joints). Error: "
                  "largest relative error of dG/dk, dG/dc, dG/dphi0 against the reference; last column: the "
                  "largest relative difference to the same method and setting on `slider_crank.yaml` (IDA: "
                  "separate adaptive runs).\n")
        md.append(mr.markdown_table(["integrator", "setting", "method", "status", "error vs reference",
                                     "vs the non-redundant model"], redundant_rows))

    # csv
    csv_name = "gradients.csv"
    with open(os.path.join(OUT, csv_name), "w", newline="") as fcsv:
        w = csv.writer(fcsv)
        w.writerow(["integrator", "setting", "x", "method", "wrt", "G", "dG_dk", "dG_dc", "dG_dphi0", "err_G",
                    "err_k", "err_c", "err_phi0", "solver_cpu_time", "gradient_cpu_time", "forward_steps", "runs",
                    "status"])
        for c in cases:
            w.writerow([c.integrator, c.setting, "%g" % c.x, method_label(c), " ".join(c.wrt),
                        "%.16g" % c.value if c.value is not None else ""] +
                       ["%.16g" % c.grad[p] if p in c.grad else "" for p in PARAMS] +
                       ["%.3e" % c.err_G if c.err_G is not None else ""] +
                       ["%.3e" % c.err[p] if p in c.err else "" for p in PARAMS] +
                       [c.cpu if c.cpu is not None else "", c.gcpu if c.gcpu is not None else "",
                        c.steps if c.steps is not None else "", c.runs if c.runs is not None else "", c.status])

    figures = []
    if not args.quick:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, (a1, a2) = plt.subplots(1, 2, figsize=(11.5, 4.6))
        styles = {"adjoint": ("o-", "adjoint"), "forward": ("x--", "forward"),
                  "fd (step 1e-3)": ("s", "fd, relative step 1e-3"), "fd extrapolated to step 0": ("D", "fd extrapolated to step 0")}

        def plotted(c, m):
            return c.status == "done" and method_label(c) == m
        for m, (st, lab) in styles.items():
            pts = sorted((c.x, c.max_err()) for c in cases if c.integrator == "hht" and plotted(c, m))
            if pts:
                a1.loglog([p[0] for p in pts], [p[1] for p in pts], st, color="C0" if m != "forward" else "C3",
                          ms=6 if "fd" not in m else 8, mfc="none", label="HHT fixed, %s" % lab)
        pts = sorted((c.x, c.err_G) for c in cases if c.integrator == "hht" and c.method == "adjoint"
                     and c.status == "done")
        if pts:
            a1.loglog([p[0] for p in pts], [p[1] for p in pts], "k:", label="HHT fixed, error of G itself")
            hs = np.array([p[0] for p in pts])
            e0 = max(p[1] for p in pts)
            a1.loglog(hs, 0.5 * e0 * (hs / hs.max())**2, "k-.", lw=0.8, label="slope 2")
        a1.axhline(1e-6, color="r", lw=0.8, ls="--", label="1e-6 (acceptance)")
        a1.set_xlabel("HHT step h [s]")
        a1.set_ylabel("max(k, c) |dG/dp - ref| / |ref|")
        a1.set_title("Slider-crank: gradient error, HHT fixed step")
        a1.grid(True, which="both", alpha=0.3)
        a1.legend(fontsize=7)
        colors = {"hht-adaptive": "C1", "ida": "C2"}
        for integ, col in colors.items():
            name = "HHT adaptive" if integ == "hht-adaptive" else "IDA"
            for m, (st, lab) in styles.items():
                pts = sorted((c.x, c.max_err()) for c in cases if c.integrator == integ and plotted(c, m))
                if pts:
                    a2.loglog([p[0] for p in pts], [p[1] for p in pts], st, color=col, ms=6 if "fd" not in m else 8,
                              mfc="none", label="%s, %s" % (name, lab))
            pts = sorted((c.x, c.err_G) for c in cases if c.integrator == integ and c.method == "adjoint"
                         and c.status == "done")
            if pts:
                a2.loglog([p[0] for p in pts], [p[1] for p in pts], ":", color=col, lw=1,
                          label="%s, error of G itself" % name)
        a2.axhline(1e-6, color="r", lw=0.8, ls="--", label="1e-6 (acceptance)")
        a2.set_xlabel("tolerance (HHT adaptive: tol; IDA: rtol, atol = rtol/10)")
        a2.set_ylabel("max(k, c) |dG/dp - ref| / |ref|")
        a2.set_title("Slider-crank: gradient error, adaptive integrators")
        a2.grid(True, which="both", alpha=0.3)
        a2.legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(os.path.join(OUT, "convergence.png"), dpi=100)
        figures.append("convergence.png")
        md.append("\n![convergence](convergence.png)\n")

    md.append("\nWall time of the study: %.0f s.\n" % (time.time() - t_start))
    md.append("## Checks\n")

    def err_of(integ, x, m):
        c = find(integ, x, m)
        return c.max_err() if c and c.status == "done" else float("nan")
    summary = {
        "title": "Slider-crank gradients (SUNDIALS idasSlCrank)",
        "headline": "dG/dk, dG/dc against a DOP853 sensitivity reference: HHT h = %.4g adjoint %.1e, HHT adaptive "
                    "tol %.0e adjoint %.1e, IDA rtol %.0e adjoint %.1e, forward %.1e (the SUNDIALS example: %.1e)"
                    % (h_tight, err_of("hht", h_tight, "adjoint"), tol_tight,
                       err_of("hht-adaptive", tol_tight, "adjoint"), rtol_tight,
                       err_of("ida", rtol_tight, "adjoint"), err_of("ida", rtol_tight, "forward"),
                       max(ref["sundials"]["relative_difference_gradient_k_c"]["forward"])),
        "figures": figures,
        "csv": [csv_name],
        "reference": {"G": ref["G"], "gradient": ref["gradient"]},
    }
    return mr.finish_checks(runner, checks, md, OUT, summary)


if __name__ == "__main__":
    sys.exit(main())
