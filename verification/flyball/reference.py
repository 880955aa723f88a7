"""Independent reference for IFToMM A05 (stiff flyball governor) with the shaft turning
at the imposed constant speed: the Lagrange equations in the two minimal coordinates
theta (angle of both rods below the horizontal; the motion stays symmetric) and z (the
slider's height, the benchmark's s), integrated with scipy's Radau at rtol = atol = 1e-12.
The derivation is in README.md ("Reference 2: minimal coordinates")."""
import math

import numpy as np
from scipy.integrate import solve_ivp

# data of the benchmark (README.md); rods and shaft 1 x 0.01 x 0.01 m, density 3000
RHO, W = 3000.0, 0.01
M_ROD = RHO * 1.0 * W * W                 # 0.3 kg
J_AX = M_ROD * (W * W + W * W) / 12       # rod about its own axis
J_TR = M_ROD * (1.0 + W * W) / 12         # rod about a transverse axis through its centre
M_BALL = 5.0
M_SLIDER = RHO * 0.1 ** 3                 # 3 kg
E = 0.05                                  # hinge offset from the shaft axis = half slider width
H = 1.0                                   # height of the hinges (top of the shaft)
K, C, L0 = 8.0e5, 4.0e4, 0.5
G = 9.81
OMEGA = 2 * math.pi
THETA0, Z0 = math.radians(30.0), 0.5

A_EFF = 2 * (0.25 * M_ROD + J_TR + M_BALL)  # coefficient of theta'' (two rods)


def spring(theta, z):
    """Length of one spring and its partial derivatives (rod midpoint - slider side point)."""
    c, s = math.cos(theta), math.sin(theta)
    dx, dz = 0.5 * c, H - 0.5 * s - z
    l = math.hypot(dx, dz)
    l_th = (dx * (-0.5 * s) + dz * (-0.5 * c)) / l
    l_z = -dz / l
    return l, l_th, l_z


def rhs(t, y, omega=OMEGA):
    theta, z, th_d, z_d = y
    c, s = math.cos(theta), math.sin(theta)
    # W(theta) = omega^2 [m_r (e + c/2)^2 + m_b (e + c)^2 + J_ax s^2 + J_tr c^2]  (both rods)
    dW = omega ** 2 * (-M_ROD * (E + 0.5 * c) * s - 2 * M_BALL * (E + c) * s
                       + 2 * (J_AX - J_TR) * s * c)
    dVg = -G * c * (M_ROD + 2 * M_BALL)        # d/dtheta of the rods' and balls' gravity
    l, l_th, l_z = spring(theta, z)
    F = K * (l - L0) + C * (l_th * th_d + l_z * z_d)   # tension of one spring
    th_dd = (dW - dVg - 2 * F * l_th) / A_EFF
    z_dd = (-M_SLIDER * G - 2 * F * l_z) / M_SLIDER
    return [th_d, z_d, th_dd, z_dd]


def solve(t_eval, rtol=1e-12, atol=1e-12, method="Radau"):
    """Returns (theta, z) at t_eval."""
    sol = solve_ivp(rhs, (0.0, float(t_eval[-1])), [THETA0, Z0, 0.0, 0.0], method=method,
                    t_eval=t_eval, rtol=rtol, atol=atol, jac=None)
    if not sol.success:
        raise RuntimeError("reference integration failed: " + sol.message)
    return sol.y[0], sol.y[1], sol


if __name__ == "__main__":
    t = np.linspace(0, 10, 1001)
    th, z, sol = solve(t)
    print("nfev", sol.nfev, "z(10) = %.12f" % z[-1], "theta(10) = %.12f" % th[-1])
    th2, z2, _ = solve(t, rtol=1e-10, atol=1e-10)
    print("rtol 1e-10 vs 1e-12: max |dz| = %.2e" % np.max(np.abs(z2 - z)))
