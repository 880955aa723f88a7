"""Motion-joint reactions and efforts in the results file of `mbdae simulate`.

The 3-axis arm of models/arm_motion.yaml (examples/robot_energy's arm driven by three
motion joints along quintic rest-to-rest motions from the horizontal pose): the datasets
/joints/driveK/{force,torque,effort} against a Newton-Euler computation in numpy (written
here from the geometry alone), at t = 0 (rest, arm horizontal: shoulder 9.3195 N m, elbow
1.962 N m) and at every row.
"""
import os
import subprocess

import h5py
import numpy as np

MBDAE = os.environ["MBDAE_BIN"]
MODELS = os.environ["MBDAE_APP_MODELS"]

G = 9.81
L1, L2, L3 = 0.4, 0.3, 0.2
M = [3.0, 2.0, 1.0, 0.5]
RR, RP = 0.02, 0.03
Q0 = np.zeros(3)
QT = np.array([1.5, 0.9, -0.3])


def rz(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def ry(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def angles(t, T=1.0):
    s = t / T
    p = 10 * s**3 - 15 * s**4 + 6 * s**5
    dp = (30 * s**2 - 60 * s**3 + 30 * s**4) / T
    ddp = (60 * s - 180 * s**2 + 120 * s**3) / T**2
    d = QT - Q0
    return Q0 + d * p, d * dp, d * ddp


def newton_euler(q, qd, qdd):
    """Actuator torques about the base, shoulder and elbow axes."""
    R = [rz(q[0]), rz(q[0]) @ ry(-q[1]), rz(q[0]) @ ry(-(q[1] + q[2]))]
    R.append(R[2])
    z = [np.array([0, 0, 1.0]), R[0] @ np.array([0, -1.0, 0])]
    z.append(z[1])
    w1 = qd[0] * z[0]
    w2 = w1 + qd[1] * z[1]
    w3 = w2 + qd[2] * z[2]
    dw1 = qdd[0] * z[0]
    dw2 = dw1 + qdd[1] * z[1] + np.cross(w1, qd[1] * z[1])
    dw3 = dw2 + qdd[2] * z[2] + np.cross(w1, qd[2] * z[2])
    w, dw = [w1, w2, w3, w3], [dw1, dw2, dw3, dw3]
    S = np.array([0, 0, L1])
    E = S + R[1] @ np.array([L2, 0, 0])

    def acc(aA, wb, dwb, r):
        return aA + np.cross(dwb, r) + np.cross(wb, np.cross(wb, r))

    c = [np.array([0, 0, L1 / 2]), S + R[1] @ np.array([L2 / 2, 0, 0]),
         E + R[2] @ np.array([L3 / 2, 0, 0]), E + R[2] @ np.array([L3, 0, 0])]
    aE = acc(np.zeros(3), w2, dw2, E - S)
    a = [acc(np.zeros(3), w1, dw1, c[0]), acc(np.zeros(3), w2, dw2, c[1] - S),
         acc(aE, w3, dw3, c[2] - E), acc(aE, w3, dw3, c[3] - E)]
    J = [np.diag([M[0] * (3 * RR**2 + L1**2) / 12] * 2 + [M[0] * RR**2 / 2]),
         np.diag([M[1] * RR**2 / 2] + [M[1] * (3 * RR**2 + L2**2) / 12] * 2),
         np.diag([M[2] * RR**2 / 2] + [M[2] * (3 * RR**2 + L3**2) / 12] * 2),
         0.4 * M[3] * RP**2 * np.eye(3)]
    g = np.array([0, 0, -G])
    points = [np.zeros(3), S, E]
    tau = np.zeros(3)
    for j in range(3):
        n = np.zeros(3)
        for b in range(j, 4):
            f = M[b] * (a[b] - g)
            I = R[b] @ J[b] @ R[b].T
            n += np.cross(c[b] - points[j], f) + I @ dw[b] + np.cross(w[b], I @ w[b])
        tau[j] = z[j] @ n
    return tau


def simulate(tmp_path, *args):
    out = str(tmp_path / "arm.h5")
    subprocess.run([MBDAE, "simulate", os.path.join(MODELS, "arm_motion.yaml"), "-o", out,
                    "--quiet", *args], check=True)
    return out


def test_static_horizontal_efforts(tmp_path):
    with h5py.File(simulate(tmp_path), "r") as f:
        assert f.attrs["output_accelerations"] == "solved"
        assert f.attrs["rows_with_integrator_accelerations"] == 0
        effort = [f[f"/joints/drive{k}/effort"][0] for k in (1, 2, 3)]
        np.testing.assert_allclose(effort, [0.0, 9.3195, 1.962], atol=1e-9)
        np.testing.assert_allclose(newton_euler(*angles(0.0)), [0.0, 9.3195, 1.962], atol=1e-12)
        np.testing.assert_allclose(f["/joints/drive2/torque"][0], [0, -9.3195, 0], atol=1e-9)
        np.testing.assert_allclose(f["/joints/drive2/force"][0], [0, 0, 0], atol=1e-9)
        # The revolute shoulder takes no torque about its axis (-y) and carries 3.5 kg.
        assert abs(f["/joints/shoulder/torque"][0][1]) < 1e-9
        np.testing.assert_allclose(f["/joints/shoulder/force"][0], [0, 0, 3.5 * G], atol=1e-9)
        # Ordinary joints have no effort dataset.
        assert "effort" not in f["/joints/shoulder"]
        # The effort is -lambda of the joint's equation.
        names = list(f["/lambda_names"].asstr()[:])
        lam = f["/lambda"][:, names.index("drive2.motion")]
        np.testing.assert_allclose(f["/joints/drive2/effort"][:], -lam, rtol=0, atol=1e-12)


def test_efforts_along_the_motion(tmp_path):
    with h5py.File(simulate(tmp_path), "r") as f:
        t = f["/time"][:]
        effort = np.column_stack([f[f"/joints/drive{k}/effort"][:] for k in (1, 2, 3)])
    reference = np.array([newton_euler(*angles(tk)) for tk in t])
    error = np.abs(effort - reference).max()
    # IDA at rtol 1e-8, atol 1e-10; the efforts solved from the rows' (t, q, v).
    assert error < 1e-6, error
