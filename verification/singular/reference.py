#!/usr/bin/env python3
"""Reference of the parallelogram four-bar (fourbar.yaml): the crank angle on the
parallelogram branch, by two independent integrators of its one-degree-of-freedom ODE.

On the parallelogram branch the two cranks keep the same angle phi (from the upward
vertical, clockwise: the crank tops at (x_k + L sin phi, L cos phi)) and the coupler
translates without turning. Lagrange in phi: the cranks are rods of mass m turning about
their pins (m L^2 / 3 each), the coupler translates with the speed L phi' of the crank
tops (m L^2 phi'^2 / 2); the centres are at heights L/2 cos phi (cranks) and L cos phi
(coupler):

    J phi'' = G sin phi,   J = m L^2 (2/3 + 1) = 5/3 m L^2,   G = m g L (1 + 1) = 2 m g L,
    phi'' = k sin phi,     k = 6 g / (5 L) = 11.772 1/s^2,   phi(0) = 0, phi'(0) = v0 / L.

(IFToMM A02's equation, verification/nfourbar/reference.py, with N = 1.) The energy
integral phi'^2 = w0^2 + 4 k sin^2(phi / 2) never vanishes: the linkage turns round and
round and is horizontal (the loop's Jacobian singular) at phi = pi/2 + j pi.

The reference is the solution of that ODE by scipy's DOP853 (explicit Runge-Kutta 8(5,3))
and by Radau (implicit Runge-Kutta, order 5), each at rtol = 1e-13; their difference is
the reference's stated accuracy (self_check). The program's crank angle is
phi = pi/2 - phi0, phi0 the measure of the model (crank 0's axis from world x).
"""
import math

import numpy as np
from scipy import integrate

L, M, G_ACC, V0 = 1.0, 1.0, 9.81, 1.0
T_END = 10.0


def k_constant(L=L, g=G_ACC):
    return 6.0 * g / (5.0 * L)


def _rhs(_, s, k):
    return [s[1], k * math.sin(s[0])]


def solve(method="DOP853", t_end=T_END, rtol=1e-13, atol=1e-14):
    """Dense solution of phi'' = k sin phi (scipy OdeSolution: sol(t) -> [phi, phi'])."""
    k = k_constant()
    sol = integrate.solve_ivp(_rhs, (0.0, t_end), [0.0, V0 / L], method=method, rtol=rtol,
                              atol=atol, dense_output=True, args=(k,),
                              **({"jac": lambda _, s, k: [[0.0, 1.0], [k * math.cos(s[0]), 0.0]]}
                                 if method == "Radau" else {}))
    if not sol.success:
        raise RuntimeError("reference: %s failed: %s" % (method, sol.message))
    return sol.sol


_DOP = None


def phi(t):
    """Crank angle phi(t) (rad; array) from DOP853 at rtol = 1e-13."""
    global _DOP
    if _DOP is None:
        _DOP = solve("DOP853")
    return _DOP(np.asarray(t, float))[0]


def self_check():
    """Largest |phi_DOP853 - phi_Radau| over 0..T_END (rad) and the energy-integral residual
    max |phi'^2 - w0^2 - 4 k sin^2(phi/2)| of DOP853."""
    t = np.linspace(0.0, T_END, 2001)
    a = solve("DOP853")(t)
    b = solve("Radau")(t)
    k = k_constant()
    energy = np.abs(a[1] ** 2 - (V0 / L) ** 2 - 4 * k * np.sin(0.5 * a[0]) ** 2)
    return float(np.max(np.abs(a[0] - b[0]))), float(np.max(energy))


def singular_times(t_end=T_END):
    """Times at which phi = pi/2 + j pi (all links horizontal), by root finding on DOP853."""
    t = np.linspace(0.0, t_end, 20001)
    p = phi(t)
    j = np.floor((p - 0.5 * math.pi) / math.pi)
    out = []
    for i in np.where(np.diff(j) > 0)[0]:
        target = (j[i + 1] + 0.5) * math.pi
        from scipy.optimize import brentq
        out.append(brentq(lambda s: phi(np.array([s]))[0] - target, t[i], t[i + 1], xtol=1e-14))
    return np.array(out)


if __name__ == "__main__":
    d, e = self_check()
    print("DOP853 vs Radau (rtol 1e-13): max |dphi| = %.2e rad; energy residual %.2e" % (d, e))
    ts = singular_times()
    print("%d singular passages in %g s: %s" % (len(ts), T_END, ", ".join("%.4f" % x for x in ts)))
    print("phi(10) = %.15f" % phi(np.array([T_END]))[0])
