#!/usr/bin/env python3
"""Virtual iteration: find the force history that makes a single-mass oscillator follow a
target motion, by iterating in the frequency domain with the FRF (the example of the
FreeDyn paper's fdApi.py, on the mbdae Python package).

    PYTHONPATH=build/python /usr/bin/python3 examples/virtual_iteration/virtual_iteration.py

Steps:
1. The target motion x_target(t): three sine components under a smooth window (at rest at
   both ends, so its periodic extension is smooth and its spectrum has no leakage).
2. The FRF H(omega) = X(omega) / F(omega) from the model, through the API: at the state of
   rest, the mass matrix M, the stiffness K = d(M a)/dq + d(C_q^T lambda)/dq - dQ/dq and the
   damping D = -dQ/dq' (model matrices), projected on the null space N of the constraint
   Jacobian C_q (the motion the joints allow); the input vector b is the generalised force
   of a unit drive force (the difference of the external-force vector with the drive spline
   at 1 and at 0) and the output vector c the gradient of the measure x:
       H(omega) = c^T N (N^T (K + i omega D - omega^2 M) N)^-1 N^T b.
   It is checked against an FRF measured by simulation (a small force pulse through the
   same model, output spectrum divided by input spectrum).
3. The iteration (as in the paper): U_1 = X_target / H, then for k = 1, 2, ...: simulate
   u_k = irfft(U_k) (set as the drive spline's points), X_k = rfft(x_k), and
   U_{k+1} = U_k + alpha (X_target - X_k) / H, with alpha halved (and the step retaken
   from the best iterate) when the error grows. Updates are made only below --f-max.
   It stops when max |x_k - x_target| < --tol * max |x_target|.

By default the oscillator is made moderately nonlinear (a hardening spring force
-k3 x^3, set through the model's parameter k3): the FRF of the linearisation at rest is
then only an approximation of the plant, as in real applications, and the iteration needs
several steps; --k3 0 gives the linear oscillator of the paper.

Writes convergence.png (error against iteration; target, first and final motion; the
final force) to --out (default: this folder) and prints the numbers. Exit status 0 if it
converged, 1 if not.
"""

import argparse
import os
import sys
import time

import numpy as np

import mbdae

HERE = os.path.dirname(os.path.abspath(__file__))


def target_motion(t, t_end):
    """Three sine components (m) under a smooth window: 0 before 0.5 s, rising until 1.5 s,
    falling from t_end - 3.5 s to t_end - 2.5 s, 0 after (the mass comes to rest). The
    window's ramps are quintic smooth steps s^3 (10 - 15 s + 6 s^2): the motion is twice
    continuously differentiable, so the force that produces it is continuous."""
    x = 0.020 * np.sin(2 * np.pi * 0.5 * t) + 0.010 * np.sin(2 * np.pi * 1.3 * t + 0.7) \
        + 0.004 * np.sin(2 * np.pi * 3.1 * t + 1.9)

    def smooth_step(s):
        s = np.clip(s, 0.0, 1.0)
        return s ** 3 * (10 - 15 * s + 6 * s ** 2)

    t0, t1 = 0.5, t_end - 3.5
    return smooth_step(t - t0) * (1 - smooth_step(t - t1)) * x


def simulate(m, t, u, spline="drive", measure="x"):
    """Sets the drive spline to the force samples u at times t, solves, returns x(t)."""
    m.splines[spline] = (t, u)
    m.solve()
    x = m.outputs.measure(measure)
    if x.shape != t.shape:
        raise RuntimeError("the run stored %d rows, expected %d" % (x.shape[0], t.shape[0]))
    return x


def frf_from_matrices(m, freqs, spline="drive", measure="x"):
    """H(omega) of the linearisation at rest, from the model's matrices (see the module
    docstring)."""
    import scipy.linalg

    x_drive, y_drive = m.splines[spline]
    m.splines[spline] = (x_drive, np.ones_like(y_drive))
    m.assemble()
    q_one = m.vector("external_forces")
    m.splines[spline] = (x_drive, np.zeros_like(y_drive))
    m.assemble()  # the state of rest
    b = q_one - m.vector("external_forces")  # generalised force of a unit drive force
    c = m.measure_gradient(measure)
    M = m.matrix("mass").toarray()
    K = (m.matrix("mass_acc_dq") + m.matrix("constraint_t_dq") - m.matrix("force_dq")).toarray()
    D = -m.matrix("force_dv").toarray()
    N = scipy.linalg.null_space(m.matrix("constraint_dq").toarray())
    Mr, Kr, Dr = N.T @ M @ N, N.T @ K @ N, N.T @ D @ N
    br, cr = N.T @ b, N.T @ c
    H = np.empty(len(freqs), dtype=complex)
    for i, f in enumerate(freqs):
        w = 2 * np.pi * f
        H[i] = cr @ np.linalg.solve(Kr + 1j * w * Dr - w ** 2 * Mr, br)
    return H, N.shape[1]


def frf_by_simulation(m, t, spline="drive", measure="x"):
    """H(omega) measured by simulating a small force pulse: X(omega) / U(omega)."""
    u = 1e-3 * np.exp(-0.5 * ((t - 0.5) / 0.03) ** 2)  # ~ flat spectrum up to ~10 Hz
    x = simulate(m, t, u, spline, measure)
    U = np.fft.rfft(u)
    return np.fft.rfft(x) / U, np.abs(U) / np.abs(U).max()


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--model", default=os.path.join(HERE, "oscillator.yaml"))
    p.add_argument("--out", default=HERE, help="folder of convergence.png")
    p.add_argument("--k3", type=float, default=2.5e4,
                   help="hardening stiffness, N/m^3 (0: the linear oscillator)")
    p.add_argument("--tol", type=float, default=1e-3,
                   help="stop when max|x - x_target| < tol max|x_target|")
    p.add_argument("--max-iter", type=int, default=50)
    p.add_argument("--f-max", type=float, default=15.0,
                   help="frequencies above this (Hz) are not updated")
    p.add_argument("--no-plot", action="store_true")
    args = p.parse_args(argv)

    with mbdae.Model(args.model) as m:
        m.parameters["k3"] = args.k3
        t_end = m.options["t_end"]
        dt = m.options["output_step"]
        n = int(round(t_end / dt)) + 1
        t = np.arange(n) * dt
        freqs = np.fft.rfftfreq(n, dt)
        band = freqs <= args.f_max

        x_target = target_motion(t, t_end)
        X_target = np.fft.rfft(x_target)
        amplitude = np.max(np.abs(x_target))

        t0 = time.perf_counter()
        H, dof = frf_from_matrices(m, freqs)
        H_sim, weight = frf_by_simulation(m, t)
        check = band & (freqs <= 5.0) & (weight > 1e-2)
        frf_difference = np.max(np.abs(H_sim[check] - H[check]) / np.abs(H[check]))
        print("model: %s, %d degree(s) of freedom, k3 = %g N/m^3; %d samples, dt = %g s"
              % (os.path.basename(args.model), dof, args.k3, n, dt))
        print("FRF from the model matrices: |H(0)| = %.6g m/N (1/k = %.6g), peak %.6g m/N at "
              "%.3g Hz; measured by simulation: max relative difference %.2e up to 5 Hz"
              % (abs(H[0]), 1 / m.parameters["k"], np.abs(H).max(),
                 freqs[np.argmax(np.abs(H))], frf_difference))

        U = np.where(band, X_target / H, 0)
        alpha, history, first = 1.0, [], None
        best = None  # (error, U, X) of the best iterate
        converged = False
        for it in range(1, args.max_iter + 1):
            u = np.fft.irfft(U, n)
            x = simulate(m, t, u)
            error = np.max(np.abs(x - x_target)) / amplitude
            history.append(error)
            if first is None:
                first = x.copy()
            print("iteration %2d: error %.3e (alpha %g)" % (it, error, alpha))
            if error < args.tol:
                converged = True
                break
            X = np.fft.rfft(x)
            if best is not None and error > best[0]:
                alpha /= 2  # not better: a shorter step from the best iterate
                error, U_base, X = best
                if alpha < 1e-6:
                    break
            else:
                best = (error, U.copy(), X)
                U_base = U
            U = U_base + np.where(band, alpha * (X_target - X) / H, 0)
        elapsed = time.perf_counter() - t0

    print("%s after %d iterations: error %.3e of the target's amplitude (%.4g m); "
          "%.2f s in all" % ("converged" if converged else "NOT converged", len(history),
                             history[-1], amplitude, elapsed))

    if not args.no_plot:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(3, 1, figsize=(7, 9))
        ax[0].semilogy(np.arange(1, len(history) + 1), history, "o-")
        ax[0].axhline(args.tol, color="k", ls="--", lw=0.8, label="tolerance %g" % args.tol)
        ax[0].set_xlabel("iteration")
        ax[0].xaxis.get_major_locator().set_params(integer=True)
        ax[0].set_ylabel("max |x - x_target| / max |x_target|")
        ax[0].set_title("Virtual iteration of a single-mass oscillator (k3 = %g N/m$^3$)"
                        % args.k3)
        ax[0].legend()
        ax[0].grid(True, which="both", alpha=0.3)
        ax[1].plot(t, 1e3 * x_target, "k", lw=2.5, label="target")
        ax[1].plot(t, 1e3 * first, "C1", lw=1, label="iteration 1 (U = X_target / H)")
        ax[1].plot(t, 1e3 * x, "C0--", lw=1.2, label="iteration %d" % len(history))
        ax[1].set_ylabel("x (mm)")
        ax[1].legend(fontsize=8)
        ax[1].grid(alpha=0.3)
        ax[2].plot(t, u, "C2")
        ax[2].set_xlabel("t (s)")
        ax[2].set_ylabel("drive force (N)")
        ax[2].grid(alpha=0.3)
        fig.tight_layout()
        os.makedirs(args.out, exist_ok=True)
        path = os.path.join(args.out, "convergence.png")
        fig.savefig(path, dpi=110)
        print("wrote", path)
    return 0 if converged else 1


if __name__ == "__main__":
    sys.exit(main())
