#!/usr/bin/env python3
"""Independent reference for SUNDIALS' slider-crank (idasSlCrank): G = integral over
[0, 10] s of the kinetic energy, and its derivatives with respect to the spring
stiffness k, the damping c and the initial crank angle phi0.

The mechanism in one minimal coordinate, the crank angle theta (the data and the
generalised forces of LLNL/sundials examples/idas/serial/idasSlCrank_dns.c; see
README.md): crank pin A = a (cos theta, sin theta); the rod's direction u = (cos p, sin p)
from A to the slider B = (x, 0), |B - A| = 1, so

    sin p = -a sin theta,  cos p = sqrt(1 - a^2 sin^2 theta),  x = a cos theta + cos p.

Kinetic energy T = 1/2 m(theta) theta'^2 with m = J1 + m2 x_theta^2 + J2 p_theta^2;
Lagrange's equation

    m(theta) theta'' + 1/2 m'(theta) theta'^2 = Q(theta, theta'),
    Q = -f l_theta + F X_theta,  f = k (l - l0) + c l_theta theta',

l the distance between the crank's midpoint a/2 (cos theta, sin theta) and the rod's
midpoint B - u/2, X = x + cos p the abscissa of the rod's end E = B + u where the
horizontal force F acts. x_theta, p_theta and their derivatives in closed form.

The state (theta, theta', G) and its forward sensitivities s_j = d(state)/dp_j
(s' = f_y s + f_p, s_phi0(0) = (1, 0, 0)) are integrated together with scipy's DOP853;
the Jacobians f_y, f_p are complex-step derivatives of the right-hand side (exact to
round-off: every function in it is analytic). Checks:
  - tolerance: rtol 1e-13 against rtol 1e-11 and 1e-12 (the reported error estimate);
  - the sensitivities against 4th-order central differences of the reference itself;
  - the trajectory against the SUNDIALS example's printed table (5 digits) and G, dG/dk,
    dG/dc against the example's printed values (IDAS at rtol 1e-6: about 1e-5).
Writes reference.json (next to this file, or to $MBDAE_VERIFICATION_OUT) and prints a
summary; exit 1 if a check fails.
"""
import json
import math
import os
import sys

import numpy as np
from scipy.integrate import solve_ivp

HERE = os.path.dirname(os.path.abspath(__file__))

# The example's data (idasSlCrank_dns.c, idas_ex_fwd.tex)
DATA = dict(a=0.5, J1=1.0, m2=1.0, J2=2.0, l0=1.0, F=1.0, k=1.0, c=1.0, phi0=math.pi / 2)
T_END = 10.0
# printed by the example (idasSlCrank_dns.out: y1 = theta, y2 = x, y3 = p at rtol 1e-6;
# idasSlCrank_FSA_dns.out: G and the forward-sensitivity gradient, 5 digits)
SUNDIALS_TABLE = {0.4: (1.5299e+00, 8.8672e-01, -5.2312e-01), 2.0: (5.7904e-01, 1.3803e+00, -2.7714e-01),
                  5.2: (-1.4081e+00, 9.5081e-01, 5.1599e-01), 10.0: (1.2757e+00, 1.0236e+00, -4.9881e-01)}
SUNDIALS_G = {"idasSlCrank_dns": 3.3366160662909388, "idasSlCrank_FSA_dns": 3.3366155611545363}
SUNDIALS_GRAD = {"forward": (3.3346e-01, -3.6375e-01), "centered_fd": (3.3345e-01, -3.6375e-01)}
PARAMS = ("k", "c", "phi0")


def kinematics(th, a):
    """x, p (through sin/cos), their first and second theta-derivatives; works on complex arrays."""
    s, co = np.sin(th), np.cos(th)
    sp = -a * s
    cp = np.sqrt(1.0 - a * a * s * s)
    p_t = -a * co / cp
    x = a * co + cp
    x_t = -a * s * (1.0 - p_t)
    p_tt = a * s / cp + a * a * co * s * p_t / (cp * cp)
    x_tt = -a * co * (1.0 - p_t) + a * s * p_tt
    return s, co, sp, cp, x, x_t, x_tt, p_t, p_tt


def rhs_core(th, om, k, c, d=DATA):
    """theta'', T (kinetic energy) for arrays of (theta, omega, k, c)."""
    a, J1, m2, J2, l0, F = d["a"], d["J1"], d["m2"], d["J2"], d["l0"], d["F"]
    s, co, sp, cp, x, x_t, x_tt, p_t, p_tt = kinematics(th, a)
    m = J1 + m2 * x_t**2 + J2 * p_t**2
    m_t = 2.0 * m2 * x_t * x_tt + 2.0 * J2 * p_t * p_tt
    # spring: crank midpoint P1 = a/2 (cos, sin); rod midpoint M = B - u/2
    dx = (x - 0.5 * cp) - 0.5 * a * co
    dy = (-0.5 * sp) - 0.5 * a * s
    dx_t = (x_t + 0.5 * sp * p_t) + 0.5 * a * s
    dy_t = (-0.5 * cp * p_t) - 0.5 * a * co
    l = np.sqrt(dx * dx + dy * dy)
    l_t = (dx * dx_t + dy * dy_t) / l
    f = k * (l - l0) + c * l_t * om
    X_t = x_t - sp * p_t            # E = B + u: X = x + cos p
    Q = -f * l_t + F * X_t
    acc = (Q - 0.5 * m_t * om * om) / m
    T = 0.5 * m * om * om
    return acc, T


H_CS = 1e-30


def augmented_rhs(_t, y, k, c):
    th, om = y[0], y[1]
    # complex-step perturbations: base, d/dtheta, d/domega, d/dk, d/dc
    e = np.zeros((5, 4))
    e[1, 0] = e[2, 1] = e[3, 2] = e[4, 3] = 1.0
    z = np.array([th, om, k, c])[None, :] + 1j * H_CS * e
    acc, T = rhs_core(z[:, 0], z[:, 1], z[:, 2], z[:, 3])
    f0 = np.array([om, acc[0].real, T[0].real])
    # f_y (3 x 3; the columns of theta and omega; G does not enter) and f_p (k, c, phi0)
    fy = np.array([[0.0, 1.0, 0.0],
                   [acc[1].imag / H_CS, acc[2].imag / H_CS, 0.0],
                   [T[1].imag / H_CS, T[2].imag / H_CS, 0.0]])
    fp = np.array([[0.0, 0.0, 0.0],
                   [acc[3].imag / H_CS, acc[4].imag / H_CS, 0.0],
                   [0.0, 0.0, 0.0]])
    S = y[3:].reshape(3, 3).T        # columns: s_k, s_c, s_phi0
    dS = fy @ S + fp
    return np.concatenate([f0, dS.T.ravel()])


def solve(k=DATA["k"], c=DATA["c"], phi0=DATA["phi0"], rtol=1e-13, atol=1e-15, t_eval=None):
    """(G, gradient dict, solution) at the given parameters."""
    y0 = np.zeros(12)
    y0[0] = phi0
    y0[3 + 6] = 1.0                  # d theta(0) / d phi0
    sol = solve_ivp(augmented_rhs, (0.0, T_END), y0, method="DOP853", rtol=rtol, atol=atol,
                    args=(k, c), t_eval=t_eval, dense_output=False)
    if not sol.success:
        raise RuntimeError("reference failed: " + sol.message)
    yT = sol.y[:, -1]
    grad = {"k": yT[3 + 2], "c": yT[6 + 2], "phi0": yT[9 + 2]}
    return yT[2], grad, sol


def slider_and_rod(th, a=DATA["a"]):
    s, co, sp, cp, x, *_ = kinematics(th, a)
    return x, math.atan2(sp, cp)


def main():
    out = os.environ.get("MBDAE_VERIFICATION_OUT") or HERE
    os.makedirs(out, exist_ok=True)
    checks = []
    G, grad, sol = solve(t_eval=sorted(SUNDIALS_TABLE))
    est = {}
    for tol in (1e-11, 1e-12):
        Gt, gt, _ = solve(rtol=tol, atol=tol * 1e-2)
        est[tol] = {"G": abs(Gt - G) / abs(G), **{p: abs(gt[p] - grad[p]) / abs(grad[p]) for p in PARAMS}}
    err_est = max(est[1e-11].values())
    print("G = %.15f; dG/dk = %.15f, dG/dc = %.15f, dG/dphi0 = %.15f (%d rhs evaluations)"
          % (G, grad["k"], grad["c"], grad["phi0"], sol.nfev))
    print("  relative change against rtol 1e-12: %s; 1e-11: %s"
          % (", ".join("%s %.1e" % kv for kv in est[1e-12].items()),
             ", ".join("%s %.1e" % kv for kv in est[1e-11].items())))
    checks.append(("reference at rtol 1e-13 vs 1e-11: largest relative change %.1e (tolerance 1e-9)" % err_est,
                   err_est <= 1e-9))

    # sensitivities against 4th-order central differences of the reference itself
    fd = {}
    for p, h in (("k", 1e-3), ("c", 1e-3), ("phi0", 1e-3)):
        base = {"k": DATA["k"], "c": DATA["c"], "phi0": DATA["phi0"]}

        def g_at(delta):
            kw = dict(base)
            kw[p] += delta
            return solve(**kw)[0]
        fd[p] = (8 * (g_at(h) - g_at(-h)) - (g_at(2 * h) - g_at(-2 * h))) / (12 * h)
    fd_err = {p: abs(fd[p] - grad[p]) / abs(grad[p]) for p in PARAMS}
    print("  4th-order central differences (h = 1e-3): %s" % ", ".join(
        "d/d%s %.15f (rel. diff. %.1e)" % (p, fd[p], fd_err[p]) for p in PARAMS))
    checks.append(("sensitivities vs 4th-order central differences of the reference: %s (tolerance 1e-8)"
                   % ", ".join("%s %.1e" % (p, fd_err[p]) for p in PARAMS), max(fd_err.values()) <= 1e-8))

    # the SUNDIALS example's printed trajectory (5 significant digits)
    worst = 0.0
    for j, t in enumerate(sol.t):
        x, p = slider_and_rod(sol.y[0, j])
        for v, r in zip((sol.y[0, j], x, p), SUNDIALS_TABLE[t]):
            worst = max(worst, abs(v - r) / abs(r))
    print("  SUNDIALS' printed theta, x, p at t = %s: largest relative difference %.1e"
          % (", ".join("%g" % t for t in sol.t), worst))
    checks.append(("trajectory vs the example's printed table (5 digits): %.1e (tolerance 1e-3)" % worst,
                   worst <= 1e-3))
    dG = {name: abs(v - G) / G for name, v in SUNDIALS_G.items()}
    dgrad = {name: [abs(v[0] - grad["k"]) / abs(grad["k"]), abs(v[1] - grad["c"]) / abs(grad["c"])]
             for name, v in SUNDIALS_GRAD.items()}
    print("  SUNDIALS' G: %s; gradient: %s" % (
        ", ".join("%s %.1e" % kv for kv in dG.items()),
        ", ".join("%s k %.1e c %.1e" % (n, v[0], v[1]) for n, v in dgrad.items())))
    checks.append(("G vs the examples' printed G (IDAS rtol 1e-6): %s (tolerance 1e-5)"
                   % ", ".join("%.1e" % v for v in dG.values()), max(dG.values()) <= 1e-5))
    checks.append(("dG/dk, dG/dc vs the example's printed forward and centred-difference gradients (4 digits "
                   "printed): %s (tolerance 5e-4)" % ", ".join("%.1e" % v for l in dgrad.values() for v in l),
                   max(v for l in dgrad.values() for v in l) <= 5e-4))

    data = {
        "source": "verification/slider_crank/reference.py: minimal-coordinate Lagrange equation with forward "
                  "sensitivities, scipy DOP853 rtol 1e-13 atol 1e-15",
        "problem": {k: v for k, v in DATA.items()}, "t_end": T_END,
        "G": G, "gradient": grad,
        "relative_change_vs_rtol_1e-11": est[1e-11], "relative_change_vs_rtol_1e-12": est[1e-12],
        "central_differences_4th_order": fd, "central_differences_relative_difference": fd_err,
        "sundials": {"G": SUNDIALS_G, "gradient_k_c": SUNDIALS_GRAD,
                     "relative_difference_G": dG, "relative_difference_gradient_k_c": dgrad,
                     "table_largest_relative_difference": worst},
        "checks": [{"text": t, "passed": bool(ok)} for t, ok in checks],
    }
    with open(os.path.join(out, "reference.json"), "w") as f:
        json.dump(data, f, indent=1)
        f.write("\n")
    for t, ok in checks:
        print(("ok    " if ok else "FAIL  ") + t)
    return 0 if all(ok for _, ok in checks) else 1


if __name__ == "__main__":
    sys.exit(main())
