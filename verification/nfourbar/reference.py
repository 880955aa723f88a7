#!/usr/bin/env python3
"""Reference solution of the N-four-bar mechanism (IFToMM A02) in one coordinate.

On the parallelogram branch every crank has the same angle phi (measured from the upward
vertical, positive clockwise, i.e. B0 = (L sin phi, L cos phi)) and the couplers translate.
Lagrange with the kinetic energy of N + 1 rods turning about their pins (m L^2 / 3 each)
and N translating couplers (speed L phi', m L^2 phi'^2 / 2 each), and the potential energy
of the rods' centres (cranks at height L/2 cos phi, couplers at L cos phi):

    J phi'' = G sin phi,   J = m L^2 ((N + 1)/3 + N),   G = m g L ((N + 1)/2 + N)

i.e. the inverted pendulum phi'' = k sin phi with k = G / J, phi(0) = 0,
phi'(0) = v0 / L. Its energy integral phi'^2 = w0^2 + 4 k sin^2(phi / 2), w0 = v0 / L,
never vanishes: the mechanism turns round and round, through the singular (horizontal)
positions phi = pi/2 + j pi.

Closed form: with u = phi / 2, u' = (w0 / 2) sqrt(1 - mu sin^2 u), mu = -4 k / w0^2 < 0, so
u = am(w0 t / 2 | mu), a Jacobi amplitude with a negative parameter. The reciprocal-modulus
transformation for a negative parameter (DLMF 22.17.2 with an imaginary modulus,
sn(z | -n) = sd(z sqrt(1+n) | n/(1+n)) / sqrt(1+n), cn(z | -n) = cd(z sqrt(1+n) | n/(1+n)),
dn(z | -n) = nd(z sqrt(1+n) | n/(1+n))) brings it to scipy.special.ellipj's range
0 <= m <= 1:

    s = sin(phi/2) = sd(z' | m') / sqrt(1 + n),   c = cos(phi/2) = cd(z' | m'),
    phi' = w0 nd(z' | m'),     n = 4 k / w0^2, m' = n / (1 + n), z' = (w0 t / 2) sqrt(1 + n)

    x(B0) = L sin phi = 2 L s c,   y(B0) = L cos phi = L (c^2 - s^2),
    vx(B0) = L cos(phi) phi',      vy(B0) = -L sin(phi) phi'

Two independent checks of that closed form (`python3 reference.py`):
  - DOP853 (scipy.integrate.solve_ivp) on phi'' = k sin phi at rtol = 1e-13, atol = 1e-14;
  - the energy quadrature t(phi) = integral_0^phi dpsi / sqrt(w0^2 + 4 k sin^2(psi/2))
    (scipy.integrate.quad, epsabs = epsrel = 1e-13) at the closed form's phi(t).
"""
import math
import sys

import numpy as np
from scipy import integrate, linalg, special


def constants(n=40, L=1.0, m=1.0, g=9.81, v0=1.0):
    J = m * L * L * ((n + 1) / 3.0 + n)
    G = m * g * L * ((n + 1) / 2.0 + n)
    return G / J, v0 / L


def solution(t, n=40, L=1.0, m=1.0, g=9.81, v0=1.0):
    """Closed form: dict of phi, phidot, x, y, vx, vy of B0 at the times t (array)."""
    k, w0 = constants(n, L, m, g, v0)
    t = np.asarray(t, float)
    nn = 4.0 * k / (w0 * w0)
    mp = nn / (1.0 + nn)
    z = 0.5 * w0 * t * math.sqrt(1.0 + nn)
    sn, cn, dn, ph = special.ellipj(z, mp)
    s = sn / dn / math.sqrt(1.0 + nn)       # sin(phi/2)
    c = cn / dn                             # cos(phi/2)
    phidot = w0 / dn
    # phi itself, continuous: phi/2 = am(w0 t/2 | -n) lies in the same half-turn as the
    # transformed amplitude ph = am(z' | m') (s, c have the signs of sin ph, cos ph), and
    # differs from it by less than pi/2
    d = np.arctan2(s, c) - ph
    d = (d + np.pi) % (2.0 * np.pi) - np.pi
    phi = 2.0 * (ph + d)
    x = 2.0 * L * s * c
    y = L * (c * c - s * s)
    return {"phi": phi, "phidot": phidot, "x": x, "y": y,
            "vx": y * phidot, "vy": -x * phidot}


def dop853(t, n=40, L=1.0, m=1.0, g=9.81, v0=1.0, rtol=1e-13, atol=1e-14):
    k, w0 = constants(n, L, m, g, v0)
    sol = integrate.solve_ivp(lambda _, s: [s[1], k * math.sin(s[0])], (0.0, float(t[-1])), [0.0, w0],
                              method="DOP853", t_eval=t, rtol=rtol, atol=atol)
    phi, phidot = sol.y
    return {"phi": phi, "phidot": phidot, "x": L * np.sin(phi), "y": L * np.cos(phi),
            "vx": L * np.cos(phi) * phidot, "vy": -L * np.sin(phi) * phidot}


def quadrature_times(phi, n=40, L=1.0, m=1.0, g=9.81, v0=1.0):
    """t(phi) from the energy integral, for a list of angles phi >= 0."""
    k, w0 = constants(n, L, m, g, v0)

    def f(p):
        return 1.0 / math.sqrt(w0 * w0 + 4.0 * k * math.sin(0.5 * p) ** 2)
    out = []
    for p in phi:
        # split at multiples of pi (the integrand's period) for quad's accuracy
        edges = [0.0] + [j * math.pi for j in range(1, int(p // math.pi) + 1)] + [p]
        out.append(sum(integrate.quad(f, a, b, epsabs=1e-13, epsrel=1e-13, limit=200)[0]
                       for a, b in zip(edges[:-1], edges[1:]) if b > a))
    return np.array(out)


def self_check(n=40, t_end=20.0):
    """Largest differences closed form vs DOP853 (x, vx over 401 times) and vs the energy
    quadrature (time of the closed form's angle at 41 times)."""
    t = np.linspace(0.0, t_end, 401)
    a, b = solution(t, n), dop853(t, n)
    dx = float(np.max(np.abs(a["x"] - b["x"])))
    dv = float(np.max(np.abs(a["vx"] - b["vx"])))
    tq = np.linspace(0.0, t_end, 41)
    aq = solution(tq, n)
    dt = float(np.max(np.abs(quadrature_times(aq["phi"], n) - tq)))
    return dx, dv, dt


if __name__ == "__main__":
    dx, dv, dt = self_check()
    print("closed form vs DOP853 (rtol 1e-13): max |dx| = %.2e m, max |dvx| = %.2e m/s" % (dx, dv))
    print("closed form vs energy quadrature: max |t(phi) - t| = %.2e s" % dt)
    k, w0 = constants()
    print("N = 40: k = %.15g 1/s^2, phi'(0) = %g rad/s" % (k, w0))
    sys.exit(0 if max(dx, dv, dt) < 1e-9 else 1)


def reactions(t, n=40, L=1.0, m=1.0, g=9.81, v0=1.0):
    """Planar joint reactions on the parallelogram branch, from the Newton-Euler equations of
    the 2 N + 1 links with the reference accelerations (least squares; 6 N + 3 equations,
    6 N + 2 unknown pin forces, consistent because the motion satisfies the equation of
    motion; unique away from the singular positions, where the matrix has full column rank,
    and the minimum-norm solution at them). Returns (forces, rank) with forces a dict
    joint name -> array (len(t), 2): the force of the joint on the body of its marker i
    (crank k for G_k, coupler k for A_k and C_k), as in the results file's
    /joints/NAME/force; rank: the numerical rank (relative 1e-12, QR with pivoting) at each time."""
    k_, w0 = constants(n, L, m, g, v0)
    t = np.atleast_1d(np.asarray(t, float))
    sol = solution(t, n, L, m, g, v0)
    phi, w = sol["phi"], sol["phidot"]
    alpha = k_ * np.sin(phi)
    names = ["G%d" % k for k in range(n + 1)] + ["A%d" % k for k in range(n)] + ["C%d" % k for k in range(n)]
    col = {nm: 2 * i for i, nm in enumerate(names)}
    nb = 2 * n + 1
    I = m * L * L / 12.0
    out = {nm: np.zeros((len(t), 2)) for nm in names}
    ranks = np.zeros(len(t), int)
    for it in range(len(t)):
        s, c, pd, pdd = math.sin(phi[it]), math.cos(phi[it]), w[it], alpha[it]
        u = np.array([s, c])                 # crank direction (pin to top), unit
        du = np.array([c, -s])               # d u / d phi
        acc_dir = pdd * du - pd * pd * u     # d^2 u / dt^2
        A = np.zeros((3 * nb, 2 * len(names)))
        b = np.zeros(3 * nb)

        def add(body, joint, sign, arm):
            # force sign * F_joint acting on body at arm (from its centre)
            j = col[joint]
            r = 3 * body
            A[r, j] += sign
            A[r + 1, j + 1] += sign
            A[r + 2, j] += -sign * arm[1]      # moment z = arm_x F_y - arm_y F_x
            A[r + 2, j + 1] += sign * arm[0]
        for k in range(n + 1):               # body k: crank k
            add(k, "G%d" % k, 1.0, -0.5 * L * u)
            if k < n:
                add(k, "A%d" % k, -1.0, 0.5 * L * u)
            if k > 0:
                add(k, "C%d" % (k - 1), -1.0, 0.5 * L * u)
            a = 0.5 * L * acc_dir
            b[3 * k:3 * k + 2] = m * a - np.array([0.0, -m * g])
            b[3 * k + 2] = I * (-pdd)        # crank turns clockwise: omega_z = -phi'
        for k in range(n):                   # body n + 1 + k: coupler k
            body = n + 1 + k
            add(body, "A%d" % k, 1.0, np.array([-0.5 * L, 0.0]))
            add(body, "C%d" % k, 1.0, np.array([0.5 * L, 0.0]))
            a = L * acc_dir
            b[3 * body:3 * body + 2] = m * a - np.array([0.0, -m * g])
            b[3 * body + 2] = 0.0
        x, _, rank, _ = linalg.lstsq(A, b, cond=1e-12, lapack_driver="gelsy")
        ranks[it] = rank
        for nm in names:
            out[nm][it] = x[col[nm]:col[nm] + 2]
    return out, ranks
