"""Andrews' squeezer mechanism: data, reference and geometry.

Data and reference: E. Hairer, G. Wanner, Solving Ordinary Differential Equations II,
2nd ed., Springer 1996, section VII.7 ("Andrews' squeezing mechanism"), and the Test
Set for IVP Solvers (F. Mazzia, C. Magherini, University of Bari), problem andrews.f;
the reference solution at t = 0.03 was computed there with PSIDE at rtol = atol = 1e-14.

The test set's coordinates are 7 angles: beta (body 1 against ground), Theta (body 2
against body 1), gamma (body 3 against ground), Phi (body 4 against body 5), delta
(body 5 against ground), Omega (body 6 against body 7), epsilon (body 7 against ground).
Its 6 loop-closure constraints (point E reached through bodies 1-2 and 3, 4-5, 6-7):

  rr cos(b) - d cos(b+T) - ss sin(g)                    = xb
  rr sin(b) - d sin(b+T) + ss cos(g)                    = yb
  rr cos(b) - d cos(b+T) - e sin(P+de) - zt cos(de)     = xa
  rr sin(b) - d sin(b+T) + e cos(P+de) - zt sin(de)     = ya
  rr cos(b) - d cos(b+T) - zf cos(O+ep) - u sin(ep)     = xa
  rr sin(b) - d sin(b+T) - zf sin(O+ep) + u cos(ep)     = ya

Each body here has its own frame: origin at a reference point (a joint), x axis along
the unit vector (cos a, sin a) of its absolute angle a, y axis (-sin a, cos a). The
points below are in that frame. The centres of mass follow Hairer & Wanner's figure of
the mechanism: only their distances from the joints enter the test set's mass matrix,
which check_geometry.py reproduces from these positions.
"""
import math

import numpy as np

# Masses and inertias (about the centres of mass)
m = [.04325, .00365, .02373, .00706, .07050, .00706, .05498]
inertia = [2.194e-6, 4.410e-7, 5.255e-6, 5.667e-7, 1.169e-5, 5.667e-7, 1.912e-5]
# Ground points A, B, C (the origin O is the crank's pivot)
xa, ya = -.06934, -.00227
xb, yb = -.03635, .03273
xc, yc = .014, .072
# Lengths
d, da, e, ea = 28e-3, 115e-4, 2e-2, 1421e-5
rr, ra = 7e-3, 92e-5
ss, sa, sb, sc, sd = 35e-3, 1874e-5, 1043e-5, 18e-3, 2e-2
ta, tb = 2308e-5, 916e-5
u, ua, ub = 4e-2, 1228e-5, 449e-5
zf, zt, fa = 2e-2, 4e-2, 1421e-5
# Drive torque on body 1, spring between point D of body 3 and C
mom = 33e-3
c0, l0 = 4530.0, 7785e-5

NAMES = ["beta", "Theta", "gamma", "Phi", "delta", "Omega", "epsilon"]
# Consistent initial angles (test set), velocities zero.
Q0 = np.array([-0.0617138900142764496358948458001, 0.0,
               0.455279819163070380255912382449, 0.222668390165885884674473185609,
               0.487364979543842550225598953530, -0.222668390165885884674473185609,
               1.23054744454982119249735015568])
# Reference at t = 0.03 (PSIDE, rtol = atol = 1e-14)
T_REF = 0.03
Q_REF = np.array([0.1581077119629904e+2, -0.1575637105984298e+2, 0.4082224013073101e-1,
                  -0.5347301163226948e+0, 0.5244099658805304e+0, 0.5347301163226948e+0,
                  0.1048080741042263e+1])
QD_REF = np.array([0.1139920302151208e+4, -0.1424379294994111e+4, 0.1103291221937134e+2,
                   0.1929337464421385e+2, 0.5735699284790808e+0, -0.1929337464421385e+2,
                   0.3231791658026955e+0])

# Bodies: name, reference point's name, points in the body frame (from the reference
# point), centre of mass in the same frame.
BODIES = [
    ("K1", {"O": (0, 0), "P": (rr, 0)}, (ra, 0)),
    ("K2", {"P": (0, 0), "E": (-d, 0)}, (-da, 0)),
    ("K3", {"B": (0, 0), "E": (0, -ss), "D": (sd, -sc)}, (sb, -sa)),
    ("K4", {"H": (0, 0), "E": (0, -e)}, (0, -(e - ea))),
    ("K5", {"A": (0, 0), "H": (zt, 0)}, (ta, tb)),
    ("K6", {"G": (0, 0), "E": (zf, 0)}, (zf - fa, 0)),
    ("K7", {"A": (0, 0), "G": (0, -u)}, (-ub, -ua)),
]
GROUND = {"O": (0.0, 0.0), "A": (xa, ya), "B": (xb, yb), "C": (xc, yc)}

# Revolute joints: (name, marker i, marker j)
JOINTS = [
    ("O", "K1.O", "ground.O"),
    ("P", "K2.P", "K1.P"),
    ("B", "K3.B", "ground.B"),
    ("E32", "K3.E", "K2.E"),
    ("E42", "K4.E", "K2.E"),
    ("E62", "K6.E", "K2.E"),
    ("A5", "K5.A", "ground.A"),
    ("H", "K4.H", "K5.H"),
    ("A7", "K7.A", "ground.A"),
    ("G", "K6.G", "K7.G"),
]
# Rotational measures reproducing the test set's angles: (name, marker i, marker j)
MEASURES = [
    ("beta", "K1.O", "ground.O"),
    ("Theta", "K2.P", "K1.P"),
    ("gamma", "K3.B", "ground.B"),
    ("Phi", "K4.H", "K5.H"),
    ("delta", "K5.A", "ground.A"),
    ("Omega", "K6.G", "K7.G"),
    ("epsilon", "K7.A", "ground.A"),
]


def rot(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s], [s, c]])


def absolute_angles(q):
    b, T, g, P, de, O, ep = q
    return [b, b + T, g, P + de, de, O + ep, ep]


def reference_points(q):
    """World position of each body's reference point."""
    b, T, g, P, de, O, ep = q
    A = np.array([xa, ya])
    P_ = rr * np.array([math.cos(b), math.sin(b)])
    H = A + zt * np.array([math.cos(de), math.sin(de)])
    G = A - u * np.array([-math.sin(ep), math.cos(ep)])
    return [np.zeros(2), P_, np.array([xb, yb]), H, A, G, A]


def world_point(q, body, point):
    a = absolute_angles(q)[body]
    return reference_points(q)[body] + rot(a) @ np.array(BODIES[body][1][point], float)


def centre_of_mass(q, body):
    a = absolute_angles(q)[body]
    return reference_points(q)[body] + rot(a) @ np.array(BODIES[body][2], float)


def test_set_constraints(q):
    """The test set's 6 position constraints g(q) (andrews.f)."""
    b, T, g, P, de, O, ep = q
    x = rr * math.cos(b) - d * math.cos(b + T)
    y = rr * math.sin(b) - d * math.sin(b + T)
    return np.array([
        x - ss * math.sin(g) - xb,
        y + ss * math.cos(g) - yb,
        x - e * math.sin(P + de) - zt * math.cos(de) - xa,
        y + e * math.cos(P + de) - zt * math.sin(de) - ya,
        x - zf * math.cos(O + ep) - u * math.sin(ep) - xa,
        y - zf * math.sin(O + ep) + u * math.cos(ep) - ya,
    ])


def test_set_mass_matrix(q):
    """The test set's 7 x 7 mass matrix M(q) (andrews.f)."""
    b, T, g, P, de, O, ep = q
    M = np.zeros((7, 7))
    M[0, 0] = m[0] * ra**2 + m[1] * (rr**2 - 2 * da * rr * math.cos(T) + da**2) + inertia[0] + inertia[1]
    M[1, 0] = M[0, 1] = m[1] * (da**2 - da * rr * math.cos(T)) + inertia[1]
    M[1, 1] = m[1] * da**2 + inertia[1]
    M[2, 2] = m[2] * (sa**2 + sb**2) + inertia[2]
    M[3, 3] = m[3] * (e - ea)**2 + inertia[3]
    M[4, 3] = M[3, 4] = m[3] * ((e - ea)**2 + zt * (e - ea) * math.sin(P)) + inertia[3]
    M[4, 4] = (m[3] * (zt**2 + 2 * zt * (e - ea) * math.sin(P) + (e - ea)**2)
               + m[4] * (ta**2 + tb**2) + inertia[3] + inertia[4])
    M[5, 5] = m[5] * (zf - fa)**2 + inertia[5]
    M[6, 5] = M[5, 6] = m[5] * ((zf - fa)**2 - u * (zf - fa) * math.sin(O)) + inertia[5]
    M[6, 6] = (m[5] * ((zf - fa)**2 - 2 * u * (zf - fa) * math.sin(O) + u**2)
               + m[6] * (ua**2 + ub**2) + inertia[5] + inertia[6])
    return M
